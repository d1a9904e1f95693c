#include "core/bench/window_kernels.h"

#include "core/common/scalar.h"
#include "core/estimator/estimator_probe.h"
#include "core/estimator/system_blocks.h"

namespace marglab {

double landmarkQrFlops(int m, int n) {
  double flops = 0;
  for (int k = 0; k < 3; ++k) flops += 2.0 * (m - k) + 4.0 * (m - k) * (n - k - 1);
  return flops;
}

template <typename Scalar>
struct WindowKernels<Scalar>::State {
  using Est = SlidingWindowEstimator<Scalar>;
  State(const WindowSnapshot& w, const Variant& v)
      : est(Est::fromSnapshot(w, v)),
        est_once(Est::fromSnapshot(w, v, oneIteration(w.config))),
        lin(EstimatorProbe<Scalar>::variantLinearization(est)),
        lambda(static_cast<Scalar>(w.config.lambda_init)) {}
  static EstimatorSettings oneIteration(EstimatorSettings config) {
    config.lm_max_iterations = 1;
    return config;
  }
  Est est, est_once;
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
  s_->lin->linearize(s_->est.window());
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
  typename State::Est copy = s_->est_once;
  FrameResult result;
  return EstimatorProbe<Scalar>::optimize(copy, &result);
}

template <typename Scalar>
Status WindowKernels<Scalar>::optimizeFull(int* iterations, double* cost_final) {
  typename State::Est copy = s_->est;
  FrameResult result;
  Status st = EstimatorProbe<Scalar>::optimize(copy, &result);
  *iterations = result.lm_iterations;
  if (cost_final) *cost_final = result.cost_final;
  return st;
}

template <typename Scalar>
Status WindowKernels<Scalar>::marginalize(MargMethod method) {
  const auto& est = s_->est;
  MargPlan plan;
  using Probe = EstimatorProbe<Scalar>;
  if (const auto state_plan = Probe::planStateMarginalization(est, true)) plan = *state_plan;
  const std::vector<int64_t> kfs = est.keyframeIds();
  if (!kfs.empty()) {
    const MargPlan kf = Probe::planKeyframeMarginalization(est, kfs.front());
    plan.vars.insert(kf.vars.begin(), kf.vars.end());
    plan.landmarks = kf.landmarks;
  }
  MargPrior<Scalar> prior = est.prior();
  return makeMarginalizer<Scalar>(method, prior.storage, est.window().config())
      ->marginalize(est.window(), plan, &prior, nullptr);
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
