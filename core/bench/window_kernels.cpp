#include "core/bench/window_kernels.h"

#include "core/linalg/landmark_block.h"
#include "core/linalg/rcs_solve.h"

namespace marglab {

double landmarkQrFlops(int m, int n) {
  double flops = 0;
  for (int k = 0; k < 3; ++k) flops += 2.0 * (m - k) + 4.0 * (m - k) * (n - k - 1);
  return flops;
}

// The friend of SlidingWindowEstimator: it calls the estimator's private phases.
template <typename Scalar>
class WindowKernels<Scalar>::State {
 public:
  using Est = SlidingWindowEstimator<Scalar>;
  State(const WindowSnapshot& w, const Variant& v)
      : est(Est::fromSnapshot(w, v)), ns(v.opt == OptElimination::kNullspace) {
    for (const auto& [id, frame] : est.frames_) system.insert(id);
    n = est.windowColumns(&column_of);
    lambda = static_cast<Scalar>(est.config_.lambda_init);
    lambda_min = static_cast<Scalar>(est.config_.lambda_min);
  }
  Est est;
  bool ns;
  std::set<int64_t> system;
  typename Est::ColumnMap column_of;
  int n = 0;
  Scalar lambda = 0, lambda_min = 0;
  std::vector<typename Est::Linearized> lins;
  std::vector<typename Est::LinkLinearized> links;
  std::vector<PoseBlockMap> maps;
  std::vector<LandmarkBlockNs<Scalar>> ns_blocks;
  std::vector<LandmarkBlockSc<Scalar>> sc_blocks;
  std::vector<char> active;
  MatX<Scalar> H_fixed, H;
  VecX<Scalar> b_fixed, b, delta;
};

template <typename Scalar>
WindowKernels<Scalar>::WindowKernels(const WindowSnapshot& window, const Variant& variant)
    : s_(std::make_unique<State>(window, variant)) {}

template <typename Scalar>
WindowKernels<Scalar>::~WindowKernels() = default;

template <typename Scalar>
void WindowKernels<Scalar>::linearize() {
  State& s = *s_;
  auto& est = s.est;
  const auto rel = est.relativePoses(true);
  // As optimize(): the Jacobians' storage is reused from the previous linearization.
  s.lins.resize(est.landmarks_.size());
  s.maps.resize(est.landmarks_.size());
  size_t n = 0;
  for (const auto& [id, lm] : est.landmarks_) {
    if (est.linearizeLandmark(id, lm, s.system, rel, &s.lins[n])) {
      s.maps[n] = est.blockMap(s.lins[n], s.column_of);
      ++n;
    }
  }
  s.lins.resize(n);
  s.maps.resize(n);
  s.links.assign(est.imu_links_.size(), {});
  size_t k = 0;
  for (const auto& [from, link] : est.imu_links_) est.linearizeLink(from, link, &s.links[k++]);
}

template <typename Scalar>
Status WindowKernels<Scalar>::eliminate() {
  State& s = *s_;
  auto& est = s.est;
  // IMU terms and prior, as optimize() forms them.
  s.H_fixed = MatX<Scalar>::Zero(s.n, s.n);
  s.b_fixed = VecX<Scalar>::Zero(s.n);
  for (const auto& lin : s.links) {
    const MatX<Scalar> H_link = lin.J.transpose() * lin.J;
    const VecX<Scalar> b_link = lin.J.transpose() * lin.r;
    for (int i = 0; i < 4; ++i) {
      const VarKey vi{i < 2 ? lin.from : lin.to,
                      i % 2 == 0 ? StateBlock::kPose : StateBlock::kSpeedBias};
      const int oi = (i / 2) * 15 + (i % 2) * kPoseDim, ni = stateBlockDim(vi.block);
      s.b_fixed.segment(s.column_of.at(vi), ni) += b_link.segment(oi, ni);
      for (int j = 0; j < 4; ++j) {
        const VarKey vj{j < 2 ? lin.from : lin.to,
                        j % 2 == 0 ? StateBlock::kPose : StateBlock::kSpeedBias};
        const int oj = (j / 2) * 15 + (j % 2) * kPoseDim, nj = stateBlockDim(vj.block);
        s.H_fixed.block(s.column_of.at(vi), s.column_of.at(vj), ni, nj) +=
            H_link.block(oi, oj, ni, nj);
      }
    }
  }
  if (!est.prior_.empty()) {
    MatX<Scalar> Hp;
    VecX<Scalar> bp;
    est.prior_.linearize(est.priorDelta(est.prior_), &Hp, &bp);
    for (const auto& bi : est.prior_.blocks) {
      const int ci = s.column_of.at(bi.var), ni = stateBlockDim(bi.var.block);
      s.b_fixed.segment(ci, ni) += bp.segment(bi.offset, ni);
      for (const auto& bj : est.prior_.blocks) {
        s.H_fixed.block(ci, s.column_of.at(bj.var), ni, stateBlockDim(bj.var.block)) +=
            Hp.block(bi.offset, bj.offset, ni, stateBlockDim(bj.var.block));
      }
    }
  }
  const size_t L = s.lins.size();
  s.active.assign(L, 1);
  if (s.ns) {
    s.ns_blocks.resize(L);
    for (size_t l = 0; l < L; ++l) {
      Status st =
          s.ns_blocks[l].setFromJacobians(s.lins[l].J_p, s.lins[l].J_l, s.lins[l].r, s.maps[l]);
      if (!st.ok()) return st;
      s.active[l] = s.ns_blocks[l].landmarkSolvable();
      if (s.active[l]) s.ns_blocks[l].addToReducedSystem(s.H_fixed, s.b_fixed);
    }
  } else {
    s.sc_blocks.resize(L);
    for (size_t l = 0; l < L; ++l) {
      Status st =
          s.sc_blocks[l].setFromJacobians(s.lins[l].J_p, s.lins[l].J_l, s.lins[l].r, s.maps[l]);
      if (!st.ok()) return st;
      s.active[l] = s.sc_blocks[l].addToReducedSystem(s.H_fixed, s.b_fixed).ok();
    }
  }
  return Status::Ok();
}

template <typename Scalar>
Status WindowKernels<Scalar>::solve() {
  State& s = *s_;
  const DampedSolve<Scalar> solve =
      solveDampedLdlt<Scalar>(s.H_fixed, s.b_fixed, s.lambda, s.lambda_min);
  if (!solve.status.ok()) return solve.status;
  s.delta = solve.delta;
  Vec3<Scalar> delta_l;
  for (size_t l = 0; l < s.lins.size(); ++l) {
    if (!s.active[l]) continue;
    Status st = s.ns ? s.ns_blocks[l].backSubstitute(s.delta, &delta_l)
                     : s.sc_blocks[l].backSubstitute(s.delta, &delta_l);
    if (!st.ok()) return st;
  }
  return Status::Ok();
}

template <typename Scalar>
Status WindowKernels<Scalar>::iteration() {
  linearize();
  Status st = eliminate();
  return st.ok() ? solve() : st;
}

template <typename Scalar>
Status WindowKernels<Scalar>::optimizeOnce() {
  typename State::Est copy = s_->est;
  copy.config_.lm_max_iterations = 1;
  FrameResult result;
  return copy.optimize(&result);
}

template <typename Scalar>
Status WindowKernels<Scalar>::optimizeFull(int* iterations, double* cost_final) {
  typename State::Est copy = s_->est;
  FrameResult result;
  Status st = copy.optimize(&result);
  *iterations = result.lm_iterations;
  if (cost_final) *cost_final = result.cost_final;
  return st;
}

template <typename Scalar>
Status WindowKernels<Scalar>::marginalize(MargMethod method) {
  const auto& est = s_->est;
  MargPlan plan;
  if (const auto state_plan = est.planStateMarginalization(true)) plan = *state_plan;
  const std::vector<int64_t> kfs = est.keyframeIds();
  if (!kfs.empty()) {
    const MargPlan kf = est.planKeyframeMarginalization(kfs.front());
    plan.vars.insert(kf.vars.begin(), kf.vars.end());
    plan.landmarks = kf.landmarks;
  }
  MargPrior<Scalar> prior = est.prior_;
  return est.marginalizeInto(prior, method, prior.storage, plan, nullptr);
}

template <typename Scalar>
int WindowKernels<Scalar>::numLandmarkBlocks() const {
  return static_cast<int>(s_->lins.size());
}
template <typename Scalar>
const MatX<Scalar>& WindowKernels<Scalar>::blockJp(int i) const {
  return s_->lins[i].J_p;
}
template <typename Scalar>
const Mat<Scalar, Eigen::Dynamic, 3>& WindowKernels<Scalar>::blockJl(int i) const {
  return s_->lins[i].J_l;
}
template <typename Scalar>
const VecX<Scalar>& WindowKernels<Scalar>::blockR(int i) const {
  return s_->lins[i].r;
}
template <typename Scalar>
PoseBlockMap WindowKernels<Scalar>::blockMap(int i) const {
  return s_->maps[i];
}
template <typename Scalar>
int WindowKernels<Scalar>::numColumns() const {
  return s_->n;
}
template <typename Scalar>
const VecX<Scalar>& WindowKernels<Scalar>::step() const {
  return s_->delta;
}

#define MARGLAB_INST(S) template class WindowKernels<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
