#pragma once
// The Ceres peers of `marglab ba` on the same model, start and loss: Ceres' own formulation of a
// BAL problem (its bundle_adjuster example): the Snavely residual of snavely_camera.h written on
// the stored parameters (angle-axis ω, t, f, k1, k2: one 9-vector per camera, updated additively),
// differentiated automatically; points eliminated first (ordering: points, then cameras);
// ceres::HuberLoss(δ) for --huber δ. Ceres' Huber applies its Corrector (a second-order term
// outside δ) where rootba's IRLS weighting does not; the costs ½ Σ ρ(‖r‖²) are the same function.
//
//   ceres-implicit   ITERATIVE_SCHUR, SCHUR_JACOBI, the Schur complement applied implicitly
//   ceres-explicit   ITERATIVE_SCHUR, SCHUR_JACOBI, use_explicit_schur_complement
//   ceres-sparse     SPARSE_SCHUR (a sparse Cholesky of the reduced camera system)
// LM settings as rootba passes them to Ceres: initial trust region 1/λ₀, function tolerance,
// gradient and parameter tolerances 0, at most 500 CG iterations, η, Jacobi scaling, one thread
// per --threads.

#include "core/ba/ba_options.h"
#include "core/ba/bal_problem.h"

namespace marglab {

BaResult solveWithCeres(const BalProblem& problem, const BaOptions& options);

}  // namespace marglab
