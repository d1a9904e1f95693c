#pragma once
// Access to the estimator's internal steps for the clients that take a window apart rather than
// run it: the window replay of `marglab bench` (core/bench) and the equivalence tests (the LM step
// and the prior of each elimination / marginalization method on the same window). Not part of the
// estimator's interface: processFrame() runs these steps itself.

#include <memory>
#include <optional>

#include "core/estimator/estimator.h"

namespace marglab {

template <typename Scalar>
class EstimatorProbe {
 public:
  using Estimator = SlidingWindowEstimator<Scalar>;

  // One optimize() of the window as processFrame() runs it (LM iterations until a stop rule).
  static Status optimize(Estimator& e, FrameResult* result) { return e.optimize(result); }
  // Fills window->after from the current state (after optimize()).
  static void recordStep(const Estimator& e, const FrameResult& result, WindowSnapshot* window) {
    e.recordStep(result, window);
  }
  // The linearization optimize() runs (the variant's elimination and precision).
  static std::unique_ptr<Linearization<Scalar>> variantLinearization(const Estimator& e) {
    return e.makeVariantLinearization();
  }
  // The LM step of all variables for damping λ with the given elimination (layout: frames in id
  // order, pose then speed-bias).
  static Status computeStep(const Estimator& e, OptElimination elimination, Scalar lambda,
                            VecX<Scalar>* delta) {
    return e.computeStep(elimination, lambda, delta);
  }
  // The oldest VIO state's marginalization as the estimator would plan it now (force: even within
  // max_states); nullopt for VO or with no state to spare.
  static std::optional<MargPlan> planStateMarginalization(const Estimator& e, bool force) {
    return e.planStateMarginalization(force);
  }
  // Keyframe `frame_id` with the landmarks it hosts.
  static MargPlan planKeyframeMarginalization(const Estimator& e, int64_t frame_id) {
    return e.planKeyframeMarginalization(frame_id);
  }
  // The prior Hessian `plan` would produce with `method` on a copy of the shadow prior, in double.
  static Status trialMarginalization(const Estimator& e, const MargPlan& plan, MargMethod method,
                                     MatXd* H_m) {
    return e.trialMarginalization(plan, method, H_m);
  }
};

}  // namespace marglab
