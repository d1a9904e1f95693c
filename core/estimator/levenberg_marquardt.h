#pragma once
// The Levenberg–Marquardt optimization of one frame's window (docs/design.md §3,
// Levenberg–Marquardt): the window and the variant's linearization in, the window moved to the
// optimum out, with the numbers of the frame's /frames row.
//
// Energy and model. The window's energy is E(x) = ½‖r(x)‖² over the whitened residuals
// (reprojection with Huber weights, IMU factors, recovered factors, the prior). At x the residuals
// are linearized in the increment δ (pose δ = [δt; δφ], t ← t + δt, R ← exp(δφ) R; speed-bias and
// landmarks additive, a hosted landmark's ρ clamped ≥ 0), r(x ⊞ δ) ≈ r + Jδ, which gives the
// quadratic model m(δ) = ½‖r + Jδ‖² with H = JᵀJ, g = Jᵀr. One linearization (linearization.h)
// eliminates the landmarks and solves the damped reduced system (H + D_λ) δ = −g with
// D_λ = diag(max(λ H_ii, λ_min)) (the landmarks undamped unless lm.landmark_damping); the step's
// predicted change is Δm = m(δ) − m(0) (LinearStep::model_change, < 0 for a descent step).
//
// Damping (Nielsen's rule). A step is accepted when the energy decreases, E(x ⊞ δ) < E(x); its gain
// ratio ρ = (E(x) − E(x ⊞ δ)) / −Δm (1 when Δm ≥ 0: rounding left no predicted decrease) sets
//   λ ← clamp(λ · max(1/3, 1 − (2ρ − 1)³), λ_min, λ_max),  ν ← 2,
// which shrinks λ by up to 3× for a step the model predicted well (ρ ≈ 1), keeps it for ρ = ½ and
// doubles it as ρ → 0.
// A rejected step is undone and retried on the same linearization with λ ← min(λν, λ_max),
// ν ← 2ν; a step rejected at λ_max ends the frame (no decrease even as gradient descent, converged
// as far as LM can tell). λ and ν restart at lambda_init and 2 every frame (as Basalt's
// optimize()).
//
// Stop rules (lm.stop_rule, LmStopRule in estimator_settings.h), after an accepted step of max |δ|:
//   marglab — at most lm.max_iterations linearizations; stop when (E − E_new) / E <
//             stop_relative_cost or max |δ| < stop_max_step;
//   basalt  — at most lm.max_iterations + 1 cost evaluations in all (a rejected λ trial counts, so
//             the frame may end on a rejected step); stop when E − E_new < kBasaltStopCost or
//             max |δ| < stop_max_step.
//
// Failed solves. A linear solve that fails (an LDLT pivot not positive — unless
// lm.indefinite_system = "solve", which takes the indefinite LDLT's solution as Basalt does — a
// non-finite system or step) is retried with more damping; max_failed_solves failures in a row — counted across frames,
// so that a run whose every frame needs one retry goes on — end the run as a numerical failure.

#include <map>
#include <memory>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/common/status.h"
#include "core/estimator/estimator_settings.h"
#include "core/estimator/linearization.h"
#include "core/estimator/variant.h"
#include "core/estimator/window.h"

namespace marglab {

// One frame's optimization as its /frames row reports it.
struct LmSummary {
  Status status;            // not ok: the run fails at this frame
  int lm_iterations = 0;    // linearizations whose λ trials ended (a step accepted or a stop)
  double cost_initial = 0;  // E(x) before the first step
  double cost_final = 0;    // E(x) after the last accepted step; 0 when a solve failed
};

template <typename Scalar>
class LevenbergMarquardt {
 public:
  // config: the [lm] keys (and lm.landmark_damping); variant: the linearization's landmark
  // elimination, precision and the prior storage's preconditioning.
  LevenbergMarquardt(const EstimatorSettings& config, const Variant& variant);

  // Optimizes the window in place; the states stay where the last accepted step left them.
  LmSummary optimize(Window<Scalar>* window);
  // The linearization optimize() runs (for `marglab bench`, which times its phases one by one).
  std::unique_ptr<Linearization<Scalar>> makeLinearization() const;

  // The failed solves in a row so far; a window restored from a capture continues its run's count.
  int failedSolves() const { return failed_solves_; }
  void setFailedSolves(int failed_solves) { failed_solves_ = failed_solves; }

 private:
  using Vec3S = Vec3<Scalar>;

  // The states one λ trial changes, to undo it.
  struct StepBackup {
    std::map<int64_t, typename Window<Scalar>::Frame> frames;
    std::vector<Vec3S> params;         // eliminated landmarks, in the linearization's order
    std::map<int64_t, Vec3S> reduced;  // landmarks of a dense prior
    Scalar stereo_offset = 0;
  };

  // λ trials on one linearization until the energy decreases (*cost updated) or λ reaches λ_max.
  Status iteration(Linearization<Scalar>& lin, Window<Scalar>* window, Scalar* cost, bool* stop);
  // x ← x ⊞ δ; returns max |δ| over all variables.
  static Scalar applyStep(const Linearization<Scalar>& lin, const LinearStep<Scalar>& step,
                          Window<Scalar>* window, StepBackup* backup);
  static void undoStep(const Linearization<Scalar>& lin, StepBackup&& backup,
                       Window<Scalar>* window);
  // The stop rule after an accepted step from `cost` to `new_cost`.
  bool converged(Scalar cost, Scalar new_cost, Scalar max_step) const;
  void increaseDamping();
  static Status checkFinite(const Window<Scalar>& window);

  EstimatorSettings config_;
  Variant variant_;
  Scalar lambda_;
  Scalar nu_ = Scalar(2);
  int evaluations_left_ = 0;  // of the frame's cost evaluations (stop rule basalt)
  int failed_solves_ = 0;
};

}  // namespace marglab
