#pragma once
// The mass-spring experiment of Levine's marginalization primer (2023, §6, Table 1, Fig. 3).
//
// Masses x_i ∈ R² on an n×n grid, springs to the 4-neighbours with potential energy
//   P_ij = ½ k ‖z_ij − x_i + x_j‖^p                                               (eq. 62)
// where z_ij = x̄_i − x̄_j is the rest offset. p = 2 (linear) except the two springs at each
// corner mass, which have p = 4; the masses they touch (3 per corner, 12 in all) form 𝒩. As
// least-squares residuals: p = 2 → r = √k e, p = 4 → r = √k ‖e‖ e, e = z_ij − x_i + x_j, so
// ½‖r‖² = P_ij. The pure spring energy only fixes relative positions; the four corner masses are
// therefore tied by stiff linear springs (k_anchor) to anchor points pulled out of the rest
// shape (stretched and sheared), which removes the gauge and puts the grid under tension. Only
// masses in 𝒩 carry anchors, so every mass outside 𝒩 appears in linear residuals only.
//
// The initial state is the rest grid with uniform noise (seeded).
//
// Single stage: Gauss–Newton (Ceres Levenberg–Marquardt with a 1e16 trust region, i.e. μ = 1e-16)
// on all masses for a fixed number of iterations, sparse normal Cholesky (or a dense solver,
// SingleSolver).
// Two stage (primer §6): (1) marginalize every mass outside 𝒩 (ceres_marg::marginalize); the
// prior is exact because the eliminated residuals are linear; (2) Gauss–Newton on the 12 masses of
// 𝒩 (prior + nonlinear springs + anchors) for the same number of iterations, dense normal
// Cholesky; (3) recover the eliminated masses with 𝒩 fixed: one linear least-squares solve
// (J_mᵀJ_m) δ = −J_mᵀ f by CHOLMOD — with the marginalization's factor of J_mᵀJ_m for
// sparse-schur (the eliminated residuals are linear, so J_m is the same matrix), a fresh
// factorization for the dense methods. The Gauss–Newton iterates of 𝒩 in (2) equal those of the
// single stage (the linear block is minimized exactly in both), so the final states agree to
// rounding even when 10 iterations have not fully converged (Gauss–Newton converges only linearly
// on p = 4 springs) — provided no step is rejected, which the results report.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/ceres_marg/marginalize.h"

namespace marglab::massspring {

struct GridSpec {
  int n = 5;  // masses per side, ≥ 4 (the corner sets of 𝒩 must not overlap)
  double k_linear = 1.0;
  double k_nonlinear = 1.0;
  double k_anchor = 10.0;
  double stretch = 1.0;   // anchor displacement from the rest corner, grid units
  double noise = 0.1;     // initial perturbation of every mass (uniform ±noise), grid units
  unsigned int seed = 1;  // of the initial perturbation
};

struct Spring {
  int i = 0, j = 0;  // masses
  int p = 2;         // exponent: 2 linear, 4 nonlinear
  double k = 1.0;
  Eigen::Vector2d z = Eigen::Vector2d::Zero();  // rest offset x̄_i − x̄_j
};

struct Anchor {
  int mass = 0;
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  double k = 1.0;
};

struct MassSpringSystem {
  GridSpec spec;
  int num_masses = 0;
  std::vector<double> rest;     // 2·num_masses, x̄
  std::vector<double> initial;  // 2·num_masses, the starting state of both methods
  std::vector<Spring> springs;
  std::vector<Anchor> anchors;
  std::vector<bool> in_nonlinear_set;  // per mass: touched by a p = 4 spring (𝒩)

  static MassSpringSystem grid(const GridSpec& spec);
  int nonlinearMasses() const;
  // Potential energy of each spring and anchor (springs first, then anchors) at x.
  std::vector<double> springEnergies(const std::vector<double>& x) const;
  double energy(const std::vector<double>& x) const;
};

// Ceres' own split of one Solve (Solver::Summary; wall time), ms: what is not evaluation or linear solving is
// the per-call overhead (preprocessing — program and ordering —, the minimizer's bookkeeping,
// postprocessing).
struct CeresSplit {
  double total_ms = 0, preprocess_ms = 0, evaluate_ms = 0, linear_solve_ms = 0;
  double overheadMs() const { return total_ms - evaluate_ms - linear_solve_ms; }
};

// The single stage's linear solver (primer §6: "Cholesky factorization"; the others measure what
// the choice does to the comparison). The dense ones build an N × N matrix: small grids only.
enum class SingleSolver { kSparseCholesky, kDenseCholesky, kDenseQr };

struct SingleStageResult {
  std::vector<double> x;
  double solve_ms = 0;
  CeresSplit split;
  int iterations = 0;
  int rejected_steps = 0;  // Gauss–Newton steps Ceres did not take (cost increase)
  double final_cost = 0;
  std::string termination;
};

struct TwoStageResult {
  std::vector<double> x;
  ceres_marg::MarginalizationSummary marginalization;
  double marginalize_ms = 0;  // stage 0: the marginalization call
  double stage1_ms = 0;       // Gauss–Newton on 𝒩
  CeresSplit stage1_split;
  double stage2_ms = 0;  // CHOLMOD recovery of the rest
  double total_ms = 0;
  int stage1_iterations = 0;
  int stage1_rejected_steps = 0;
  double final_cost = 0;
  Status status;
};

// Problem construction is not timed; the times are those of the solves, in CPU time of the calling
// thread (the solves are single-threaded; on an idle machine it equals wall time).
SingleStageResult solveSingleStage(const MassSpringSystem& system, int iterations,
                                   SingleSolver solver = SingleSolver::kSparseCholesky);
TwoStageResult solveTwoStage(const MassSpringSystem& system, int iterations,
                             ceres_marg::Method method);

}  // namespace marglab::massspring
