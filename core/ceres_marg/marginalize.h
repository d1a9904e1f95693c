#pragma once
// Marginalization of parameter blocks of a ceres::Problem (Levine, "A Technical Primer on
// Marginalization for Nonlinear Least Squares on Differentiable Manifolds", 2023, §4–5).
//
// Given the blocks x_m to eliminate, the residual blocks ∂x_m that involve them and their Markov
// blanket x_b (every other variable block of those residual blocks), Ceres evaluates the stacked
// residual f and the tangent-space Jacobian [J_m | J_b] of ∂x_m at (x̌_m, x̌_b) (eqs. 17–24; with a
// loss function the residuals and Jacobians are the Triggs-corrected ones of Problem::Evaluate,
// §5.3). Minimizing the linearized ½‖f + J_m δx_m + J_b δx_b‖² over δx_m leaves the prior
//
//   ½‖r̃ + R̃ · Minus(x_b, x̌_b)‖²                                             (eq. 56)
//
// which replaces x_m and ∂x_m in the problem (prior_cost.h). R̃, r̃ by one of
//   kQr          flat rank-revealing Householder QR of [J_m | J_b | f] (core/linalg/flat_qr.h,
//                eqs. 44–56): R̃ = R_22, r̃ = f'_2; dense.
//   kSchur       pseudo-Schur complement Λ_t = Λ_bb − Λ_bm Λ_mm⁺ Λ_mb, g_t = g_b − Λ_bm Λ_mm⁺ g_m
//                (core/linalg/schur.h, eqs. 25–35), then the square root of eq. 37:
//                Λ_t = U D Uᵀ, R̃ = D^{1/2} Uᵀ, r̃ = D^{-1/2} Uᵀ g_t over the eigenvalues above the
//                threshold (rank-deficient Λ_t, e.g. a gauge freedom in x_b, gives fewer rows);
//                dense.
//   kSparseSchur the same Λ_t, g_t with Λ_mm⁻¹ applied by a sparse Cholesky of J_mᵀJ_m (CHOLMOD),
//                then eq. 37. For many marginalized variables with a small blanket (mass-spring);
//                Λ_mm must be positive definite (no pseudo-inverse).
//
// Rank threshold τ (options.threshold, mode absolute or relative) is the one notion for all
// methods, stated on the Jacobian (singular-value scale):
//   kQr:  flat QR column test β ≤ τ (absolute) or β ≤ τ‖A(:,k)‖ (relative);
//   kSchur / kSparseSchur:  eigenvalues of Λ_mm (pseudo-inverse) and of Λ_t (square root) count as
//         zero when λ ≤ τ² (absolute) or λ ≤ max(τ², n·ε) · max_i Λ_ii (relative) — eigenvalues of
//         a Hessian are squared singular values, and below n·ε of its scale they are rounding
//         noise of forming and Schur-complementing it in double (n = n_m + n_b). The sparse
//         route uses a Cholesky of Λ_mm, no cut-off there.
// Default: relative, τ = √ε (scale invariant; Ceres problems are not whitened to O(1)).
//
// Linearization points: x_m is linearized where it is. x_b defaults to its current value; entries
// of options.linearization_points give another x̌_b (first-estimate Jacobians): Ceres evaluates at
// x̌_b (the values are written into the blocks and restored) and the prior is anchored there.
//
// Preconditions, checked before anything changes (failure returns a Status and leaves the problem
// exactly as it was): every block is in the problem, listed once, variable (not constant) and
// unbounded (primer §5.4: the analytic elimination drops constraints); the blanket's manifolds are
// supported (manifold_minus.h); the evaluation succeeds and is finite. Constant blocks in the
// blanket are treated as data: the prior is conditioned on their current value and has no
// columns for them. Bounds on blanket blocks stay on the blocks; the prior ignores them (§5.4).
//
// Ownership: the prior cost function is handed to the problem; if the problem was built with
// cost_function_ownership = DO_NOT_TAKE_OWNERSHIP the caller deletes summary.prior_cost.
// Performance: removing many blocks is O(problem size) each unless the problem was built with
// Problem::Options::enable_fast_removal = true.

#include <ceres/problem.h>

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/ceres_marg/prior_cost.h"
#include "core/ceres_marg/sparse_cholesky.h"
#include "core/common/status.h"
#include "core/linalg/flat_qr.h"

namespace marglab::ceres_marg {

enum class Method { kQr, kSchur, kSparseSchur };
const char* toString(Method method);
// "qr", "schur", "sparse-schur"; false on anything else.
bool parseMethod(const std::string& text, Method* method);

struct MarginalizationOptions {
  Method method = Method::kQr;
  RankThresholdMode threshold_mode = RankThresholdMode::kRelative;
  double threshold = NumericTraits<double>::sqrtEpsilon();
  // Linearization point x̌_b of blanket blocks (by block pointer, ambient values); blocks not
  // listed are linearized at their current value.
  std::map<const double*, std::vector<double>> linearization_points;
  // kSparseSchur: hand the Cholesky of Λ_mm = J_mᵀJ_m back in the summary (columns: x_m in the
  // order of `blocks`), e.g. to recover x_m later by back-substitution without a second
  // factorization.
  bool keep_factor = false;
};

struct MarginalizationSummary {
  Status status;
  Method method = Method::kQr;
  int marginalized_blocks = 0;
  int marginalized_dim = 0;  // Σ tangent sizes of x_m
  int removed_residual_blocks = 0;
  int residuals = 0;  // rows of f
  int blanket_blocks = 0;
  int blanket_dim = 0;              // Σ tangent sizes of x_b (columns of R̃)
  int constant_blanket_blocks = 0;  // constant neighbours treated as data
  int marg_rank = 0;                // rank of J_m (Λ_mm)
  int prior_rank = 0;               // rank of the prior
  int prior_rows = 0;               // rows of R̃ (= prior_rank, no prior if 0)
  double condition_number = 0;      // σ_max / σ_min of R̃ over its nonzero singular values
  RankThresholdMode threshold_mode = RankThresholdMode::kRelative;
  double threshold = 0;
  double evaluate_ms = 0;                        // Problem::Evaluate of ∂x_m
  double factorize_ms = 0;                       // QR or Schur + square root
  double total_ms = 0;                           // the whole call, including removal and insertion
  std::vector<double*> blanket;                  // x_b in the prior's parameter order
  ceres::ResidualBlockId prior_block = nullptr;  // null when there is no prior (empty blanket
  const MarginalizationPriorCost* prior_cost = nullptr;  // or rank 0)
  std::shared_ptr<const SparseNormalCholesky> factor;    // options.keep_factor, kSparseSchur
};

MarginalizationSummary marginalize(ceres::Problem* problem, const std::vector<double*>& blocks,
                                   const MarginalizationOptions& options = {});

}  // namespace marglab::ceres_marg
