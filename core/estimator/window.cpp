#include "core/estimator/window.h"

#include <algorithm>

#include "core/common/scalar.h"
#include "core/imu/preintegration.h"

namespace marglab {

template <typename Scalar>
std::vector<std::pair<VarKey, int>> LinkLinearized<Scalar>::vars() const {
  return {{{from, StateBlock::kPose}, 0},
          {{from, StateBlock::kSpeedBias}, kPoseDim},
          {{to, StateBlock::kPose}, 15},
          {{to, StateBlock::kSpeedBias}, 15 + kPoseDim}};
}

template <typename Scalar>
Window<Scalar>::Window(const EstimatorSettings& config, const StereoRig<double>& rig,
                       std::optional<ImuSetup> imu)
    : config_(config),
      noise_{static_cast<Scalar>(config.huber_px), static_cast<Scalar>(config.obs_std_px)},
      rig_input_(rig),
      rig_(rig.template cast<Scalar>()),
      imu_(std::move(imu)),
      pool_(std::make_shared<ThreadPool>(std::max(config.lm_threads, 1))) {
  if (imu_) {
    T_i_c_ = {rig.T_i_c0.template cast<Scalar>(), rig.T_i_c1.template cast<Scalar>()};
    g_w_ = imu_->g_w.template cast<Scalar>();
  } else {
    T_i_c_ = {SE3S(), rig.T_c0_c1().template cast<Scalar>()};
  }
  for (int cam = 0; cam < 2; ++cam) {
    T_c_i_[cam] = T_i_c_[cam].inverse();
    T_c_h_host_[cam] = T_c_i_[cam] * T_i_c_[0];
  }
  prior.storage = PriorStorage{};
}

template <typename Scalar>
void Window<Scalar>::setStereoOffset(Scalar c) {
  stereo_offset_ = c;
  rig_.cam1.cx = static_cast<Scalar>(rig_input_.cam1.cx) + c;
}

template <typename Scalar>
typename Window<Scalar>::SE3S Window<Scalar>::jacobianPoseOf(int64_t frame_id) const {
  const Frame& frame = frames.at(frame_id);
  return frame.linearized ? frame.T_w_i_lin : frame.T_w_i;
}

template <typename Scalar>
ImuState<Scalar> Window<Scalar>::stateOf(int64_t frame_id, StateAt at) const {
  const Frame& frame = frames.at(frame_id);
  ImuState<Scalar> s;
  s.t_ns = frame.t_ns;
  const bool first = at == StateAt::kFirstEstimate;
  s.T_w_i = first ? jacobianPoseOf(frame_id) : frame.T_w_i;
  const Vec9S& sb = first && frame.speed_bias_linearized ? frame.speed_bias_lin : frame.speed_bias;
  s.v_w = sb.template head<3>();
  s.b_g = sb.template segment<3>(3);
  s.b_a = sb.template tail<3>();
  return s;
}

template <typename Scalar>
std::vector<int64_t> Window<Scalar>::keyframeIds() const {
  std::vector<int64_t> ids;
  for (const auto& [id, frame] : frames) {
    if (frame.is_keyframe) ids.push_back(id);
  }
  return ids;
}

template <typename Scalar>
std::vector<int64_t> Window<Scalar>::stateIds() const {
  std::vector<int64_t> ids;
  for (const auto& [id, frame] : frames) {
    if (frame.has_speed_bias) ids.push_back(id);
  }
  return ids;
}

template <typename Scalar>
std::set<int64_t> Window<Scalar>::priorLandmarks() const {
  std::set<int64_t> tracks;
  for (const auto& block : prior.blocks) {
    if (block.var.block == StateBlock::kLandmark) tracks.insert(block.var.frame_id);
  }
  return tracks;
}

template <typename Scalar>
int Window<Scalar>::windowColumns(ColumnMap* column_of) const {
  int col = 0;
  for (const auto& [id, frame] : frames) {
    (*column_of)[{id, StateBlock::kPose}] = col;
    col += kPoseDim;
    if (frame.has_speed_bias) {
      (*column_of)[{id, StateBlock::kSpeedBias}] = col;
      col += kSpeedBiasDim;
    }
  }
  for (int64_t track : priorLandmarks()) {
    (*column_of)[{track, StateBlock::kLandmark}] = col;
    col += kPointDim;
  }
  if (estimatesStereoOffset()) {
    (*column_of)[kStereoOffsetVar] = col;
    col += kStereoOffsetDim;
  }
  return col;
}

template <typename Scalar>
VecX<Scalar> Window<Scalar>::priorDelta(const MargPrior<Scalar>& p) const {
  return p.delta([this](int64_t f) { return poseOf(f); },
                 [this](int64_t f) { return speedBiasOf(f); },
                 [this](int64_t track) { return landmarks.at(track).param; }, stereo_offset_);
}

template <typename Scalar>
size_t Window<Scalar>::RelativePoses::pos(int64_t frame) const {
  return static_cast<size_t>(std::lower_bound(ids.begin(), ids.end(), frame) - ids.begin());
}

template <typename Scalar>
size_t Window<Scalar>::RelativePoses::index(int64_t host, int64_t target, int cam) const {
  return at(pos(host), pos(target), cam);
}

template <typename Scalar>
typename Window<Scalar>::RelativePoses Window<Scalar>::relativePoses(
    WithJacobians jacobians) const {
  const bool with_jacobians = jacobians == WithJacobians::kYes;
  RelativePoses rel;
  for (const auto& [id, frame] : frames) rel.ids.push_back(id);
  const size_t size = rel.ids.size() * rel.ids.size() * 2;
  rel.T_ct_h.resize(size);
  if (with_jacobians) {
    rel.T_ct_h_jac.resize(size);
    rel.D_rel_h.resize(size);
    rel.D_rel_t.resize(size);
  }
  size_t host_pos = 0;
  for (const auto& [h, host] : frames) {
    size_t target_pos = 0;
    for (const auto& [t, target] : frames) {
      for (int cam = 0; cam < 2; ++cam) {
        const size_t k = rel.at(host_pos, target_pos, cam);
        if (h == t) {
          rel.T_ct_h[k] = T_c_h_host_[cam];
          if (with_jacobians) rel.T_ct_h_jac[k] = T_c_h_host_[cam];
          continue;
        }
        if (!with_jacobians) {
          rel.T_ct_h[k] = relativePose<Scalar>(host.T_w_i, T_i_c_[0], target.T_w_i, T_i_c_[cam]);
          continue;
        }
        rel.T_ct_h_jac[k] = relativePose<Scalar>(jacobianPoseOf(h), T_i_c_[0], jacobianPoseOf(t),
                                                 T_i_c_[cam], &rel.D_rel_h[k], &rel.D_rel_t[k]);
        // The residual needs its own relative pose only when a first estimate differs from the
        // current one.
        rel.T_ct_h[k] = host.linearized || target.linearized
                            ? relativePose<Scalar>(host.T_w_i, T_i_c_[0], target.T_w_i, T_i_c_[cam])
                            : rel.T_ct_h_jac[k];
      }
      ++target_pos;
    }
    ++host_pos;
  }
  return rel;
}

template <typename Scalar>
Scalar Window<Scalar>::landmarkCost(const Landmark& lm, const RelativePoses& rel) const {
  Scalar cost = 0;
  const size_t host = lm.world() ? 0 : rel.pos(lm.host);
  size_t target = 0;
  for (const auto& [frame_id, obs] : lm.obs) {
    const Vec3S p_i = lm.world() ? poseOf(frame_id).inverse() * lm.param : Vec3S::Zero();
    target = rel.next(frame_id, target);
    for (int cam = 0; cam < (obs.has_right ? 2 : 1); ++cam) {
      const Vec3S q =
          lm.world() ? T_c_i_[cam] * p_i
                     : transformLandmark<Scalar>(rel.T_ct_h[rel.at(host, target, cam)], lm.param);
      cost += reprojectionCost<Scalar>(cam == 0 ? rig_.cam0 : rig_.cam1, q,
                                       cam == 0 ? obs.uv0 : obs.uv1, noise_);
    }
  }
  for (const NfrFactor& f : lm.nfr) cost += nfrCost(f, &lm);
  return cost;
}

template <typename Scalar>
Blanket<Scalar> Window<Scalar>::nfrBlanket(const NfrFactor& f, const Landmark* lm,
                                           bool at_first_estimates) const {
  Blanket<Scalar> x(1);
  x[0].kind = f.kind;
  if (f.kind == BlanketKind::kPose) {
    x[0].T_w_i = at_first_estimates ? jacobianPoseOf(f.frame) : poseOf(f.frame);
    if (f.relativePose()) {
      x.push_back({BlanketKind::kPose,
                   kPoseDim,
                   at_first_estimates ? jacobianPoseOf(f.frame_b) : poseOf(f.frame_b),
                   {}});
    }
  } else {
    const Frame& frame = frames.at(f.frame);
    const Vec9S sb =
        at_first_estimates && frame.speed_bias_linearized ? frame.speed_bias_lin : frame.speed_bias;
    x[0].value = f.kind == BlanketKind::kVelocity ? VecX<Scalar>(sb.template head<3>())
                                                  : VecX<Scalar>(sb.template tail<6>());
  }
  if (lm != nullptr) {
    x.push_back({BlanketKind::kLandmark, kPoseDim, SE3S(),
                 at_first_estimates ? lm->jacobianPoint() : lm->param});
  }
  return x;
}

template <typename Scalar>
Scalar Window<Scalar>::nfrCost(const NfrFactor& f, const Landmark* lm) const {
  return Scalar(0.5) * f.factor.whitenedResidual(nfrBlanket(f, lm, false)).squaredNorm();
}

template <typename Scalar>
RowBlock<Scalar> Window<Scalar>::linearizeNfr(const NfrFactor& f, int64_t track_id,
                                              const Landmark* lm) const {
  // Residual at the current state, Jacobian at the first estimates, as every other residual.
  RowBlock<Scalar> out;
  MatX<Scalar> J_f;
  f.factor.whitenedResidual(nfrBlanket(f, lm, true), &J_f);
  out.r = f.factor.whitenedResidual(nfrBlanket(f, lm, false));
  out.vars.push_back({f.var(), 0});
  if (f.kind == BlanketKind::kPose) {
    if (lm != nullptr) out.vars.push_back({{track_id, StateBlock::kLandmark}, kPoseDim});
    if (f.relativePose()) out.vars.push_back({{f.frame_b, StateBlock::kPose}, kPoseDim});
    out.J = J_f;
    return out;
  }
  // A velocity or bias factor: its columns within the speed-bias block [v; b_g; b_a].
  out.J.setZero(J_f.rows(), kSpeedBiasDim);
  out.J.middleCols(f.kind == BlanketKind::kVelocity ? 0 : 3, J_f.cols()) = J_f;
  return out;
}

template <typename Scalar>
Scalar Window<Scalar>::nfrJointCost(const NfrJointFactor& f) const {
  std::vector<VecX<Scalar>> e;
  Eigen::Index m = 0;
  for (const NfrFactor& member : f.members) {
    e.push_back(member.factor.whitenedResidual(nfrBlanket(member, nullptr, false)));
    m += e.back().size();
  }
  VecX<Scalar> stacked(m);
  m = 0;
  for (const VecX<Scalar>& e_i : e) {
    stacked.segment(m, e_i.size()) = e_i;
    m += e_i.size();
  }
  return Scalar(0.5) * (f.A * stacked).squaredNorm();
}

template <typename Scalar>
RowBlock<Scalar> Window<Scalar>::linearizeNfrJoint(const NfrJointFactor& f) const {
  std::vector<RowBlock<Scalar>> rows;
  Eigen::Index m = 0, cols = 0;
  for (const NfrFactor& member : f.members) {
    rows.push_back(linearizeNfr(member, -1, nullptr));
    m += rows.back().r.size();
    cols += rows.back().J.cols();
  }
  // The members' rows block-diagonal over their (distinct) variables, then mixed by A.
  VecX<Scalar> r(m);
  MatX<Scalar> J = MatX<Scalar>::Zero(m, cols);
  RowBlock<Scalar> out;
  m = 0;
  cols = 0;
  for (const RowBlock<Scalar>& block : rows) {
    r.segment(m, block.r.size()) = block.r;
    J.block(m, cols, block.J.rows(), block.J.cols()) = block.J;
    out.vars.push_back({block.vars.front().first, static_cast<int>(cols)});
    m += block.r.size();
    cols += block.J.cols();
  }
  out.r = f.A * r;
  out.J = f.A * J;
  return out;
}

template <typename Scalar>
Scalar Window<Scalar>::linkCost(int64_t from, const ImuLink& link) const {
  const ImuState<Scalar> s_i = stateOf(from, StateAt::kCurrent);
  const ImuState<Scalar> s_j = stateOf(link.to, StateAt::kCurrent);
  return Scalar(0.5) *
         (link.factor.whitenedResidual(s_i, s_j).squaredNorm() +
          biasRandomWalkResidual<Scalar>(s_i, s_j, link.dt_s, imu_->noise).squaredNorm());
}

template <typename Scalar>
Scalar Window<Scalar>::totalCost() const {
  const RelativePoses rel = relativePoses(WithJacobians::kNo);
  std::vector<const Landmark*> lms;
  lms.reserve(landmarks.size());
  for (const auto& [id, lm] : landmarks) lms.push_back(&lm);
  std::vector<Scalar> chunk_cost(static_cast<size_t>(pool_->threads()), Scalar(0));
  pool_->forChunks(lms.size(), [&](size_t begin, size_t end, int chunk) {
    Scalar sum = 0;
    for (size_t i = begin; i < end; ++i) sum += landmarkCost(*lms[i], rel);
    chunk_cost[static_cast<size_t>(chunk)] = sum;
  });
  Scalar cost = 0;
  for (const Scalar c : chunk_cost) cost += c;
  for (const auto& [from, link] : imu_links) cost += linkCost(from, link);
  for (const NfrFactor& f : nfr_states) cost += nfrCost(f, nullptr);
  for (const NfrJointFactor& f : nfr_joint) cost += nfrJointCost(f);
  if (!prior.empty()) cost += prior.cost(priorDelta(prior));
  return cost;
}

template <typename Scalar>
std::vector<Scalar> Window<Scalar>::frameReprojectionErrors(int64_t frame_id) const {
  const SE3S& T_w_t = poseOf(frame_id);
  std::map<int64_t, SE3S> T_t_h;  // cam0 of the frame from cam0 of each host: once per host
  std::vector<Scalar> errors;
  for (const auto& [id, lm] : landmarks) {
    const auto obs = lm.obs.find(frame_id);
    if (obs == lm.obs.end() || lm.host == frame_id || lm.obs.size() < 2) continue;
    if (!lm.world() && !T_t_h.count(lm.host)) {
      T_t_h.emplace(lm.host, relativePose<Scalar>(poseOf(lm.host), T_i_c_[0], T_w_t, T_i_c_[0]));
    }
    const Vec3S q = lm.world() ? T_c_i_[0] * (T_w_t.inverse() * lm.param)
                               : transformLandmark<Scalar>(T_t_h.at(lm.host), lm.param);
    Vec2S uv;
    errors.push_back(rig_.cam0.project(q, &uv) ? (uv - obs->second.uv0).norm()
                                               : std::numeric_limits<Scalar>::infinity());
  }
  return errors;
}

template <typename Scalar>
bool Window<Scalar>::landmarkRows(int64_t track_id, const std::set<int64_t>& system_frames,
                                  const RelativePoses& rel, NfrRows nfr,
                                  RowBlock<Scalar>* out) const {
  LandmarkJacobians<Scalar> lin;
  if (!linearizeLandmark(track_id, landmarks.at(track_id), system_frames, rel, &lin, nfr, 1)) {
    return false;
  }
  out->vars.clear();
  for (size_t i = 0; i < lin.frames.size(); ++i) {
    out->vars.push_back({{lin.frames[i], StateBlock::kPose}, kPoseDim * static_cast<int>(i)});
  }
  const Eigen::Index n_p = lin.J_p.cols();
  if (lin.stereo_offset) out->vars.push_back({kStereoOffsetVar, static_cast<int>(n_p) - 1});
  out->vars.push_back({{track_id, StateBlock::kLandmark}, static_cast<int>(n_p)});
  out->J.resize(lin.r.size(), n_p + kPointDim);
  out->J << lin.J_p, lin.J_l;
  out->r = std::move(lin.r);
  return true;
}

template <typename Scalar>
std::vector<RowBlock<Scalar>> Window<Scalar>::directRows(const std::set<int64_t>& system_frames,
                                                         const RelativePoses& rel) const {
  std::vector<RowBlock<Scalar>> out;
  for (int64_t track : priorLandmarks()) {
    RowBlock<Scalar> rows;
    if (landmarkRows(track, system_frames, rel, NfrRows::kInclude, &rows))
      out.push_back(std::move(rows));
  }
  for (const NfrFactor& f : nfr_states) out.push_back(linearizeNfr(f, -1, nullptr));
  for (const NfrJointFactor& f : nfr_joint) out.push_back(linearizeNfrJoint(f));
  return out;
}

template <typename Scalar>
LinkLinearized<Scalar> Window<Scalar>::linearizeLink(int64_t from, const ImuLink& link) const {
  LinkLinearized<Scalar> out;
  out.from = from;
  out.to = link.to;
  const ImuState<Scalar> s_i = stateOf(from, StateAt::kCurrent);
  const ImuState<Scalar> s_j = stateOf(link.to, StateAt::kCurrent);
  const ImuState<Scalar> s_i_jac = stateOf(from, StateAt::kFirstEstimate);
  const ImuState<Scalar> s_j_jac = stateOf(link.to, StateAt::kFirstEstimate);
  typename ImuFactor<Scalar>::Jacobian J_imu;
  Mat<Scalar, 6, 30> J_rw;
  link.factor.whitenedResidual(s_i_jac, s_j_jac, &J_imu);
  biasRandomWalkResidual<Scalar>(s_i_jac, s_j_jac, link.dt_s, imu_->noise, &J_rw);
  out.J.template topRows<9>() = J_imu;
  out.J.template bottomRows<6>() = J_rw;
  out.r.template head<9>() = link.factor.whitenedResidual(s_i, s_j);
  out.r.template tail<6>() = biasRandomWalkResidual<Scalar>(s_i, s_j, link.dt_s, imu_->noise);
  return out;
}

template <typename Scalar>
typename Window<Scalar>::ImuLink Window<Scalar>::makeImuLink(int64_t from, int64_t to,
                                                             const Eigen::Vector3d& b_g,
                                                             const Eigen::Vector3d& b_a) const {
  const ImuPreintegration<double> pre = preintegrate<double>(
      imu_->imu, frames.at(from).t_ns, frames.at(to).t_ns, b_g, b_a,
      ImuSampleNoise<double>::fromDensities(imu_->noise, imu_->sample_period_s));
  return ImuLink{to, ImuFactor<Scalar>(pre.template cast<Scalar>(), g_w_),
                 static_cast<Scalar>(pre.durationSeconds())};
}

template <typename Scalar>
void Window<Scalar>::dropMarginalizedFactors(const MargPlan& plan) {
  for (const auto& [track, frame] : plan.kept_landmark_obs) {
    landmarks.at(track).obs.erase(frame);
  }
  // Recovered factors on marginalized variables are in the prior now.
  auto in_plan = [&plan](const NfrFactor& f) { return f.touches(plan.vars); };
  nfr_states.erase(std::remove_if(nfr_states.begin(), nfr_states.end(), in_plan), nfr_states.end());
  nfr_joint.erase(std::remove_if(nfr_joint.begin(), nfr_joint.end(),
                                 [&plan](const NfrJointFactor& f) { return f.touches(plan.vars); }),
                  nfr_joint.end());
  for (auto& [id, lm] : landmarks) {
    lm.nfr.erase(std::remove_if(lm.nfr.begin(), lm.nfr.end(), in_plan), lm.nfr.end());
  }
}

template <typename Scalar>
void Window<Scalar>::fixFirstEstimates() {
  for (const auto& block : prior.blocks) {
    // The stereo offset's Jacobian is constant: no first estimate to keep.
    if (block.var.block == StateBlock::kStereoOffset) continue;
    if (block.var.block == StateBlock::kLandmark) {
      Landmark& lm = landmarks.at(block.var.frame_id);
      if (!lm.linearized) {
        lm.linearized = true;
        lm.param_lin = lm.param;
      }
      continue;
    }
    Frame& frame = frames.at(block.var.frame_id);
    if (block.var.block == StateBlock::kPose && !frame.linearized) {
      frame.linearized = true;
      frame.T_w_i_lin = frame.T_w_i;
    } else if (block.var.block == StateBlock::kSpeedBias && !frame.speed_bias_linearized) {
      frame.speed_bias_linearized = true;
      frame.speed_bias_lin = frame.speed_bias;
    }
  }
}

template <typename Scalar>
void Window<Scalar>::removeMarginalized(const MargPlan& plan) {
  for (int64_t id : plan.landmarks) landmarks.erase(id);
  for (int64_t from : plan.imu_links) imu_links.erase(from);
  for (const VarKey& var : plan.vars) {
    if (var.block == StateBlock::kLandmark) {
      landmarks.erase(var.frame_id);
    } else if (var.block == StateBlock::kPose) {
      frames.erase(var.frame_id);
    } else if (auto it = frames.find(var.frame_id); it != frames.end()) {
      it->second.has_speed_bias = false;
      it->second.speed_bias_linearized = false;
    }
  }
}

#define MARGLAB_INST(S)              \
  template struct LinkLinearized<S>; \
  template class Window<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
