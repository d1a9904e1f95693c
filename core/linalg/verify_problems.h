#pragma once
// Random marginalization problems and an independent reference for them, used by
// `marglab verify` and by the tests.
//
// Reference: the pseudo-Schur complement (paper eqs. 22–25) computed in long double from the
// compact SVD of J_μ = U₁D₁V₁ᵀ, with r appended to the kept columns:
//     [J_κ r]ᵀ (I − U₁U₁ᵀ) [J_κ r] = ⎡H̃  b̃⎤
//                                   ⎣b̃ᵀ  ·⎦
// so neither H nor a pseudo-inverse of H_μμ is formed.
//
// Error bounds. Both algorithms are compared with the reference in relative Frobenius norm
// against a tolerance derived from first-order perturbation theory, with A = [J | r],
// A_κ = [J_κ | r], σ = σ_min⁺(J_μ) (smallest non-zero singular value), n = columns of A:
//   flat QR (backward stable, ‖E‖ ≤ c n ε ‖A‖; the projector moves by ‖E‖/σ):
//       tol_qr = c n ε ‖A‖ (2‖A_κ‖ + ‖A_κ‖²/σ) / ‖H̃‖
//   Schur complement on H = AᵀA formed in the scalar type (‖δH‖ ≤ c n ε ‖A‖²):
//       tol_sc = c n ε ‖A‖² (1 + ‖A_κ‖‖J_μ‖/σ²)² / ‖H̃‖
// with c = 10. The b̃ error uses ‖b̃‖ in place of ‖H̃‖. The squared σ in tol_sc is the paper's
// point: the Hessian squares the condition number.

#include <cstdint>
#include <string>
#include <vector>

#include "core/common/eigen_types.h"

namespace marglab {

enum class ProblemKind { kFullRank, kRankDeficientMarg, kCoupledRankDeficiency, kIllConditioned };
const char* toString(ProblemKind kind);

struct ProblemSpec {
  ProblemKind kind = ProblemKind::kFullRank;
  int n_rows = 40;
  int n_marg = 6;
  int n_keep = 12;
  int marg_rank_deficit = 0;  // kRankDeficientMarg: rank(J_μ) = n_marg − deficit
  double condition = 1.0;     // kIllConditioned: κ(J)
  std::uint64_t seed = 1;
};

struct TestProblem {
  ProblemSpec spec;
  MatXd J;  // [J_μ | J_κ]
  VecXd r;
};

TestProblem makeProblem(const ProblemSpec& spec);
// The suite of `marglab verify`: full rank, rank-deficient J_μ, coupled rank deficiency
// (eq. 26 violated), ill-conditioned with κ(J) = 1e2 … 1e8.
std::vector<ProblemSpec> standardProblemSpecs();

struct PseudoSchurReference {
  MatXd H_tilde;
  VecXd b_tilde;
  int rank_marg = 0;   // numerical rank of J_μ
  int rank_total = 0;  // numerical rank of J
  // A singular value within a factor 10 of the cut-off: the rank is a knife-edge decision that a
  // pivoting-free QR need not reproduce, so it is reported but not judged.
  bool rank_marg_ambiguous = false;
  bool rank_total_ambiguous = false;
  double sigma_min_marg = 0;  // smallest non-zero singular value of J_μ
  double norm_A = 0;          // ‖[J r]‖₂
  double norm_A_keep = 0;     // ‖[J_κ r]‖₂
  double norm_J_marg = 0;     // ‖J_μ‖₂
};

// rel_rank_tol: singular values ≤ rel_rank_tol · σ_max count as zero (both for J_μ and J).
PseudoSchurReference pseudoSchurReference(const MatXd& J, const VecXd& r, int n_marg,
                                          double rel_rank_tol);

struct ErrorTolerances {
  double H_qr, b_qr, H_sc, b_sc;
};
ErrorTolerances errorTolerances(const PseudoSchurReference& ref, int n_cols, double epsilon);

}  // namespace marglab
