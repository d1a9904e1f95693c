#pragma once
// The peer of issue #8: a captured window (WindowSnapshot) as a ceres::Problem with the estimator's
// energy term by term, solved by Ceres' Levenberg–Marquardt with any of its linear solvers (the
// bench tries DENSE_SCHUR, SPARSE_SCHUR, ITERATIVE_SCHUR with SCHUR_JACOBI, and DENSE_QR).
//
//   reprojection  residual (π_c(T_ct_h ℓ) − z)/σ with ceres::HuberLoss(k/σ): Ceres' cost ½ρ(s),
//                 s = ‖r‖², is then ½e²/σ² for e ≤ k and (k e − ½k²)/σ² above — the estimator's
//                 Huber norm divided by σ²; Ceres applies its own (Triggs-corrected) robust
//                 Jacobian instead of the estimator's IRLS row weights √w/σ, so the LM paths
//                 differ slightly while the stationary points are the same;
//   IMU           [W r_imu; r_rw] (15 rows) from core/imu (ImuFactor::whitenedResidual,
//                 biasRandomWalkResidual) over (pose_i, sb_i, pose_j, sb_j);
//   prior         ½‖r_m + J_m (x ⊟ x⁰)‖² (square-root prior; the Hessian storage is not supported).
// First-estimate Jacobians as in the estimator: residuals at the current values, Jacobians of
// frames with a linearization point at that point, and the prior's Jacobian J_m.
//
// Parameter blocks: poses as 7 doubles (qx qy qz qw tx ty tz) on the estimator's manifold
// (T ⊞ δ = (exp(δφ)R, t + δt), δ = [δt; δφ]); the cost functions return the tangent Jacobian in
// the first six ambient columns and the manifold's PlusJacobian is [I₆; 0], so Ceres works with
// exactly the estimator's 6-column Jacobians. Speed-bias blocks 9 doubles, landmarks (u, v, ρ)
// with ρ ≥ 0 as a bound (the estimator clamps). For the Schur solvers landmarks are eliminated
// first (ordering group 0); DENSE_QR factors the whole Jacobian.
//
// LM settings mapped from the estimator config: initial trust region 1/λ_init, radius range
// [1/λ_max, 1/λ_min], max_num_iterations = lm.max_iterations, function_tolerance =
// stop_relative_cost, no Jacobian scaling (the estimator has none), one thread. The estimator's
// absolute max|δ| < stop_max_step has no Ceres equivalent (parameter_tolerance is relative to ‖x‖
// and on KITTI stops before the first step); it is left out (parameter_tolerance 1e-12). Ceres
// damps with diag(JᵀJ)/μ clamped to [min_lm_diagonal, max_lm_diagonal] where the estimator adds
// max(λH_ii, λ_min): the same rule up to the floor.

#include <ceres/types.h>

#include "core/estimator/estimator.h"

namespace marglab {

struct CeresWindowOptions {
  ceres::LinearSolverType linear_solver = ceres::DENSE_SCHUR;
  // ITERATIVE_SCHUR only (the others are direct).
  ceres::PreconditionerType preconditioner = ceres::SCHUR_JACOBI;
  // Overrides of the window's LM stopping rules (≤ 0: from the window's config).
  int max_iterations = 0;
  double function_tolerance = -1;
  double parameter_tolerance = -1;
  double gradient_tolerance = 1e-10;
};

// Where Ceres' time went (Solver::Summary). minimizer_s contains linear_solver_s, residual_s and
// jacobian_s; total = preprocessor_s + minimizer_s + postprocessor_s.
struct CeresTimeSplit {
  double preprocessor_s = 0;
  double minimizer_s = 0;
  double linear_solver_s = 0;
  double residual_s = 0;
  double jacobian_s = 0;
  double postprocessor_s = 0;
};

struct CeresWindowResult {
  bool ok = false;
  std::string message;
  int iterations = 0;             // Ceres iterations (successful and unsuccessful)
  int successful_iterations = 0;  // accepted steps
  double seconds = 0;             // Solver::Summary::total_time_in_seconds
  CeresTimeSplit split;
  double cost_initial = 0, cost_final = 0;
  int num_residual_blocks = 0;
  WindowSnapshot::Step step;  // states after the solve
};

// Throws InputError for a window Ceres cannot represent (Hessian prior).
CeresWindowResult solveWindowWithCeres(const WindowSnapshot& window,
                                       const CeresWindowOptions& options = {});

}  // namespace marglab
