#include "core/bench/window_kernels.h"

#include "core/common/scalar.h"
#include "core/estimator/marg_policy.h"
#include "core/estimator/system_blocks.h"

namespace marglab {

double landmarkQrFlops(int m, int n) {
  double flops = 0;
  for (int k = 0; k < 3; ++k) flops += 2.0 * (m - k) + 4.0 * (m - k) * (n - k - 1);
  return flops;
}

// The captured window, the optimizer as the run configured it and as with one LM iteration, and
// the linearization whose phases linearize() / eliminate() / solve() time.
template <typename Scalar>
struct WindowKernels<Scalar>::State {
  State(const WindowSnapshot& w, const Variant& v)
      : window(restoredWindow<Scalar>(w, v, w.config)),
        lm(w.config, v),
        lm_once(oneIteration(w.config), v),
        lin(lm.makeLinearization()),
        lambda(static_cast<Scalar>(w.config.lambda_init)) {
    lm.setFailedSolves(w.failed_solves);
    lm_once.setFailedSolves(w.failed_solves);
  }
  static EstimatorSettings oneIteration(EstimatorSettings config) {
    config.lm_max_iterations = 1;
    return config;
  }
  Window<Scalar> window;
  LevenbergMarquardt<Scalar> lm, lm_once;
  std::unique_ptr<Linearization<Scalar>> lin;
  Scalar lambda;
  LinearStep<Scalar> step;
};

template <typename Scalar>
WindowKernels<Scalar>::WindowKernels(const WindowSnapshot& window, const Variant& variant)
    : s_(std::make_unique<State>(window, variant)) {}

template <typename Scalar>
WindowKernels<Scalar>::~WindowKernels() = default;

template <typename Scalar>
void WindowKernels<Scalar>::linearize() {
  s_->lin->linearize(s_->window);
}

template <typename Scalar>
Status WindowKernels<Scalar>::eliminate() {
  return s_->lin->eliminate();
}

template <typename Scalar>
Status WindowKernels<Scalar>::solve() {
  return s_->lin->solve(s_->lambda, &s_->step);
}

template <typename Scalar>
Status WindowKernels<Scalar>::iteration() {
  linearize();
  Status st = eliminate();
  return st.ok() ? solve() : st;
}

template <typename Scalar>
Status WindowKernels<Scalar>::optimizeOnce() {
  Window<Scalar> window = s_->window;
  LevenbergMarquardt<Scalar> lm = s_->lm_once;
  return lm.optimize(&window).status;
}

template <typename Scalar>
Status WindowKernels<Scalar>::optimizeFull(int* iterations, double* cost_final) {
  Window<Scalar> window = s_->window;
  LevenbergMarquardt<Scalar> lm = s_->lm;
  const LmSummary summary = lm.optimize(&window);
  *iterations = summary.lm_iterations;
  if (cost_final) *cost_final = summary.cost_final;
  return summary.status;
}

template <typename Scalar>
Status WindowKernels<Scalar>::marginalize(MargMethod method) {
  const Window<Scalar>& window = s_->window;
  const MarginalizationPolicy<Scalar> policy(window.config());
  MargPlan plan;
  if (const auto state_plan = policy.stateMarginalization(window, true)) plan = *state_plan;
  const std::vector<int64_t> kfs = window.keyframeIds();
  if (!kfs.empty()) {
    const MargPlan kf = policy.keyframeMarginalization(window, kfs.front());
    plan.vars.insert(kf.vars.begin(), kf.vars.end());
    plan.landmarks = kf.landmarks;
  }
  MargPrior<Scalar> prior = window.prior;
  return makeMarginalizer<Scalar>(method, prior.storage, window.config())
      ->marginalize(window, plan, &prior, nullptr);
}

template <typename Scalar>
int WindowKernels<Scalar>::numLandmarkBlocks() const {
  return static_cast<int>(s_->lin->landmarks().size());
}
template <typename Scalar>
const MatX<Scalar>& WindowKernels<Scalar>::blockJp(int i) const {
  return s_->lin->landmarks()[i].J_p;
}
template <typename Scalar>
const Mat<Scalar, Eigen::Dynamic, 3>& WindowKernels<Scalar>::blockJl(int i) const {
  return s_->lin->landmarks()[i].J_l;
}
template <typename Scalar>
const VecX<Scalar>& WindowKernels<Scalar>::blockR(int i) const {
  return s_->lin->landmarks()[i].r;
}
template <typename Scalar>
PoseBlockMap WindowKernels<Scalar>::blockMap(int i) const {
  return marglab::blockMap(s_->lin->landmarks()[i], s_->lin->columns());
}
template <typename Scalar>
const std::vector<LandmarkJacobians<Scalar>>& WindowKernels<Scalar>::landmarkJacobians() const {
  return s_->lin->landmarks();
}
template <typename Scalar>
int WindowKernels<Scalar>::numColumns() const {
  return s_->lin->numColumns();
}
template <typename Scalar>
const VecX<Scalar>& WindowKernels<Scalar>::step() const {
  return s_->step.delta;
}

#define MARGLAB_INST(S) template class WindowKernels<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
