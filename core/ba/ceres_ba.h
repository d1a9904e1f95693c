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

#include <ceres/rotation.h>

#include "core/ba/ba_options.h"
#include "core/ba/ba_state.h"
#include "core/ba/bal_problem.h"

namespace marglab {

// The BAL residual as Ceres' bundle_adjuster writes it (SnavelyReprojectionError), on the stored
// parameters: camera = (ω, t, f, k1, k2), point X; P = R(ω) X + t, p = −P_xy / P_z,
// r = f (1 + k1‖p‖² + k2‖p‖⁴) p − z. For ceres::AutoDiffCostFunction<SnavelyResidual, 2, 9, 3>.
struct SnavelyResidual {
  Vec<double, 2> z;
  template <typename T>
  bool operator()(const T* camera, const T* point, T* residual) const {
    T P[3];
    ceres::AngleAxisRotatePoint(camera, point, P);
    for (int i = 0; i < 3; ++i) P[i] += camera[3 + i];
    const T px = -P[0] / P[2];
    const T py = -P[1] / P[2];
    const T u = px * px + py * py;
    const T d = T(1) + u * (camera[7] + u * camera[8]);
    residual[0] = camera[6] * d * px - T(z.x());
    residual[1] = camera[6] * d * py - T(z.y());
    return true;
  }
};

// An invalid step (Ceres' linear solver failed: for ceres-sparse CHOLMOD's "Matrix not positive
// definite") records Ceres' own warning as its message ("invalid step: ...").
BaResult solveWithCeres(const BalProblem& problem, const BaOptions& options,
                        BalState<double>* solution = nullptr);

// Ceres writes those warnings through glog to stderr; a program that records them in its results
// calls this once first: glog then writes no log files and only errors to stderr, and the
// warnings reach the results only. Does nothing when glog is already initialized.
void keepCeresWarningsOffStderr();

}  // namespace marglab
