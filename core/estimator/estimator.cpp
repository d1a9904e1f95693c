#include "core/estimator/estimator.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/common/scalar.h"
#include "core/geometry/stereographic.h"
#include "core/imu/preintegration.h"

namespace marglab {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

int MargEvent::numPoses() const {
  return static_cast<int>(std::count_if(layout.begin(), layout.end(), [](const PriorVariable& v) {
    return v.kind == PriorVariableKind::kPose;
  }));
}

template <typename Scalar>
SlidingWindowEstimator<Scalar>::SlidingWindowEstimator(
    const EstimatorSettings& config, const Variant& variant, const StereoRig<double>& rig,
    const SE3<double>& T_w_i_initial, std::optional<ImuSetup> imu, EstimatorReporting reporting)
    : config_(config),
      reporting_(reporting),
      variant_(variant),
      window_(config, rig, std::move(imu)),
      policy_(config_),
      marginalizer_(makeMarginalizer<Scalar>(
          variant.marg, withPsdHessianPrior(variant.storage, config.psd_hessian_prior), config)),
      last_pose_(window_.isVio() ? window_.imu()->initial.T_w_i : T_w_i_initial),
      lm_(config, variant) {
  window_.prior.storage = withPsdHessianPrior(variant.storage, config.psd_hessian_prior);
  shadow_prior_.storage = window_.prior.storage;
}

// ---------------------------------------------------------------------------------------------
// Frame intake and keyframes

template <typename Scalar>
FrameResult SlidingWindowEstimator<Scalar>::processFrame(const TrackFrame& track_frame) {
  FrameResult result;
  result.t_ns = track_frame.t_ns;
  const int64_t id = next_frame_index_++;
  const int connected = addFrame(id, track_frame);
  result.n_connected = connected;
  if (id == 0) {
    Frame& first = window_.frames.at(id);
    first.is_keyframe = true;
    first.linearized = true;
    first.speed_bias_linearized = first.has_speed_bias;
    first.speed_bias_lin = first.speed_bias;
    last_keyframe_ = id;
    initializeGaugePrior(id);  // the shadow prior has none
    addNewLandmarks(id, track_frame);
  }

  if (capture_next_) captured_ = snapshot();
  const auto t0 = Clock::now();
  const LmSummary lm = lm_.optimize(&window_);
  result.t_opt_s = secondsSince(t0);
  result.status = lm.status;
  result.lm_iterations = lm.lm_iterations;
  result.cost_initial = lm.cost_initial;
  result.cost_final = lm.cost_final;
  if (window_.estimatesStereoOffset()) {
    result.right_cx_offset_px = static_cast<double>(window_.stereoOffset());
  }
  if (capture_next_) {
    captured_->after = stepOf(window_, lm.lm_iterations, lm.cost_initial, lm.cost_final);
    capture_next_ = false;
  }
  const Frame& optimized = window_.frames.at(id);
  const SE3<double> T_w_i = optimized.T_w_i.template cast<double>();
  result.p_est = T_w_i.translation();
  result.q_est = T_w_i.unitQuaternion();
  if (optimized.has_speed_bias) {
    result.v_w = optimized.speed_bias.template head<3>().template cast<double>();
  }
  if (!result.status.ok()) return result;
  countInconsistent(id, &result);

  updateKeyframe(id, track_frame, connected);
  result.is_keyframe = window_.frames.at(id).is_keyframe;
  result.n_landmarks = numLandmarks();
  for (const auto& [lid, lm] : window_.landmarks) {
    for (const auto& [f, obs] : lm.obs) result.n_observations += obs.has_right ? 2 : 1;
  }
  result.status = marginalize(id, &result);

  previous_pose_ = last_pose_;
  last_pose_ = T_w_i;
  has_previous_pose_ = id > 0;
  return result;
}

template <typename Scalar>
std::optional<SE3<double>> SlidingWindowEstimator<Scalar>::predictPose(int64_t t_ns) const {
  if (window_.frames.empty()) return std::nullopt;
  if (!isVio()) {
    // As addFrame: T_k = (T_{k−1} T_{k−2}⁻¹) T_{k−1}.
    return has_previous_pose_ ? (last_pose_ * previous_pose_.inverse()) * last_pose_ : last_pose_;
  }
  const int64_t newest = window_.frames.rbegin()->first;
  const ImuState<double> s_i = window_.stateOf(newest, StateAt::kCurrent).template cast<double>();
  const ImuSetup& imu = *window_.imu();
  const ImuPreintegration<double> pre =
      preintegrate<double>(imu.imu, s_i.t_ns, t_ns, s_i.b_g, s_i.b_a,
                           ImuSampleNoise<double>::fromDensities(imu.noise, imu.sample_period_s));
  return predictState<double>(s_i, pre, imu.g_w).T_w_i;
}

template <typename Scalar>
std::optional<SE3<double>> SlidingWindowEstimator<Scalar>::newestPose() const {
  if (window_.frames.empty()) return std::nullopt;
  return window_.frames.rbegin()->second.T_w_i.template cast<double>();
}

template <typename Scalar>
std::vector<std::pair<int64_t, Eigen::Vector3d>> SlidingWindowEstimator<Scalar>::landmarkPoints()
    const {
  std::vector<std::pair<int64_t, Eigen::Vector3d>> points;
  const SE3<double> T_i_c0 = window_.T_i_c(0).template cast<double>();
  for (const auto& [id, lm] : window_.landmarks) {
    const Eigen::Vector3d param = lm.param.template cast<double>();
    if (lm.world()) {
      points.emplace_back(id, param);
    } else if (param.z() > 0) {
      const SE3<double> T_w_h = window_.frames.at(lm.host).T_w_i.template cast<double>() * T_i_c0;
      points.emplace_back(id, T_w_h * landmarkToPoint<double>(param));
    }
  }
  return points;
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::countInconsistent(int64_t id, FrameResult* result) const {
  const std::vector<Scalar> errors = window_.frameReprojectionErrors(id);
  const Scalar bound = static_cast<Scalar>(reporting_.inconsistent_px);
  result->n_checked = static_cast<int>(errors.size());
  result->n_inconsistent = static_cast<int>(
      std::count_if(errors.begin(), errors.end(), [bound](Scalar e) { return !(e <= bound); }));
}

template <typename Scalar>
int SlidingWindowEstimator<Scalar>::addFrame(int64_t id, const TrackFrame& track_frame) {
  Frame frame;
  frame.t_ns = track_frame.t_ns;
  frame.has_speed_bias = isVio();
  if (isVio() && id == 0) {
    const ImuState<Scalar> s = window_.imu()->initial.template cast<Scalar>();
    frame.T_w_i = s.T_w_i;
    frame.speed_bias << s.v_w, s.b_g, s.b_a;
  } else if (!isVio()) {
    SE3<double> T_init = last_pose_;
    if (has_previous_pose_) {
      // Constant-velocity prediction: T_k = (T_{k−1} T_{k−2}⁻¹) T_{k−1}.
      T_init = (last_pose_ * previous_pose_.inverse()) * last_pose_;
    }
    frame.T_w_i = T_init.template cast<Scalar>();
  }
  frame.T_w_i_lin = frame.T_w_i;
  if (isVio() && id > 0) {
    // Predicted from the previous state through the new IMU factor.
    const int64_t previous = window_.frames.rbegin()->first;
    window_.frames[id] = frame;
    addImuLink(previous, id);
    const ImuState<Scalar> s_j =
        predictState<Scalar>(window_.stateOf(previous, StateAt::kCurrent),
                             window_.imu_links.at(previous).factor.preintegration(),
                             window_.imu()->g_w.template cast<Scalar>());
    Frame& added = window_.frames.at(id);
    added.T_w_i = s_j.T_w_i;
    added.T_w_i_lin = s_j.T_w_i;
    added.speed_bias << s_j.v_w, s_j.b_g, s_j.b_a;
  } else {
    window_.frames[id] = frame;
  }
  int connected = 0;
  for (const StereoObservation& obs : track_frame.observations) {
    auto it = window_.landmarks.find(obs.track_id);
    if (it == window_.landmarks.end()) continue;
    ++connected;
    it->second.obs[id] = {obs.uv0.template cast<Scalar>(), obs.has_right,
                          obs.uv1.template cast<Scalar>()};
  }
  return connected;
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::updateKeyframe(int64_t id, const TrackFrame& frame,
                                                    int connected) {
  const double observed = static_cast<double>(frame.observations.size());
  if (id > 0 && (observed == 0 || connected < config_.kf_connected_ratio * observed) &&
      id - last_keyframe_ >= config_.min_frames_after_kf) {
    window_.frames.at(id).is_keyframe = true;
    last_keyframe_ = id;
    addNewLandmarks(id, frame);
  }
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::addNewLandmarks(int64_t frame_id, const TrackFrame& frame) {
  TriangulationOptions<Scalar> options;
  options.min_baseline = static_cast<Scalar>(config_.min_baseline_m);
  for (const StereoObservation& obs : frame.observations) {
    if (!obs.has_right || window_.landmarks.count(obs.track_id) != 0) continue;
    const Vec<Scalar, 2> uv0 = obs.uv0.template cast<Scalar>();
    const Vec<Scalar, 2> uv1 = obs.uv1.template cast<Scalar>();
    Vec3S p_c0;
    if (!window_.rig().triangulate(uv0, uv1, &p_c0, options)) continue;
    Landmark lm;
    lm.host = frame_id;
    lm.param = landmarkFromPoint<Scalar>(p_c0);
    lm.obs[frame_id] = {uv0, true, uv1};
    window_.landmarks.emplace(obs.track_id, std::move(lm));
  }
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::initializeGaugePrior(int64_t frame_id) {
  // Weights on the first state's increment: VO all 6 pose dof; VIO position, yaw (δφ_z, the
  // rotation about gravity) and the biases.
  const Frame& first = window_.frames.at(frame_id);
  VecXd weights = VecXd::Zero(first.has_speed_bias ? 15 : 6);
  if (first.has_speed_bias) {
    weights.head<3>().setConstant(config_.gauge_prior_weight);
    weights[5] = config_.gauge_prior_weight;
    weights.segment<3>(kPoseDim + 3).setConstant(config_.gauge_prior_bias_gyro);
    weights.segment<3>(kPoseDim + 6).setConstant(config_.gauge_prior_bias_accel);
  } else {
    weights.setConstant(config_.gauge_prior_weight);
  }
  if (window_.estimatesStereoOffset()) {
    // The stereo offset's prior 1/σ_c² (its starting value 0: the loaded calibration).
    weights.conservativeResize(weights.size() + 1);
    weights[weights.size() - 1] =
        1.0 / (config_.right_cx_offset_prior_px * config_.right_cx_offset_prior_px);
  }
  const int n = static_cast<int>(weights.size());
  const int m = static_cast<int>((weights.array() > 0).count());
  MargPrior<Scalar>& prior = window_.prior;
  prior.blocks.clear();
  prior.addBlock({frame_id, StateBlock::kPose}, first.T_w_i, first.speed_bias);
  if (first.has_speed_bias) {
    prior.addBlock({frame_id, StateBlock::kSpeedBias}, first.T_w_i, first.speed_bias);
  }
  if (window_.estimatesStereoOffset()) {
    prior.addBlock(kStereoOffsetVar, first.T_w_i, first.speed_bias);
    prior.blocks.back().c0 = window_.stereoOffset();
  }
  MatX<Scalar> J = MatX<Scalar>::Zero(m, n), H = MatX<Scalar>::Zero(n, n);
  for (int c = 0, row = 0; c < n; ++c) {
    if (weights[c] <= 0) continue;
    const Scalar w = static_cast<Scalar>(weights[c]);
    J(row++, c) = std::sqrt(w);
    H(c, c) = w;
  }
  prior.setSqrt(std::move(J), VecX<Scalar>::Zero(m));
  prior.setHessian(std::move(H), VecX<Scalar>::Zero(n), Scalar(0));
  prior.precondition();
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::addImuLink(int64_t from, int64_t to) {
  // Preintegrated in double (measurement preprocessing, like the pixel measurements), then used in
  // the estimator's precision.
  const ImuState<Scalar> s_i = window_.stateOf(from, StateAt::kCurrent);
  auto link = window_.makeImuLink(from, to, s_i.b_g.template cast<double>(),
                                  s_i.b_a.template cast<double>());
  window_.imu_links.erase(from);
  window_.imu_links.emplace(from, std::move(link));
}

// ---------------------------------------------------------------------------------------------
// Window capture

template <typename Scalar>
std::optional<WindowSnapshot> SlidingWindowEstimator<Scalar>::takeCapturedWindow() {
  std::optional<WindowSnapshot> out = std::move(captured_);
  captured_.reset();
  return out;
}

template <typename Scalar>
WindowSnapshot SlidingWindowEstimator<Scalar>::snapshot() const {
  WindowSnapshot w = snapshotOf(window_);
  w.variant = variant_.name();
  w.config = config_;
  w.failed_solves = lm_.failedSolves();
  return w;
}

template <typename Scalar>
SlidingWindowEstimator<Scalar> SlidingWindowEstimator<Scalar>::fromSnapshot(
    const WindowSnapshot& w, const Variant& variant,
    const std::optional<EstimatorSettings>& config) {
  const EstimatorSettings& settings = config ? *config : w.config;
  Window<Scalar> window = restoredWindow<Scalar>(w, variant, settings);
  EstimatorReporting reporting;
  reporting.shadow_prior = false;  // a restored window has no shadow prior
  SlidingWindowEstimator est(settings, variant, w.rig, w.frames.front().T_w_i,
                             imuSetupOf<Scalar>(w), reporting);
  est.window_ = std::move(window);
  for (const auto& fs : w.frames) {
    if (fs.is_keyframe) est.last_keyframe_ = std::max(est.last_keyframe_, fs.id);
    est.next_frame_index_ = std::max(est.next_frame_index_, fs.id + 1);
  }
  est.lm_.setFailedSolves(w.failed_solves);
  return est;
}

// ---------------------------------------------------------------------------------------------
// Marginalization

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::marginalize(int64_t current, FrameResult* result) {
  const bool current_is_kf = window_.frames.at(current).is_keyframe;
  const MargDecision decision = policy_.decide(window_, current);
  applyEdits(decision.edits, &window_);
  if (!decision.plan.empty()) {
    if (Status s = marginalizePlan(decision.plan, decision.keyframe.has_value(), result); !s.ok()) {
      return s;
    }
  }
  if (!isVio() && !current_is_kf) window_.frames.erase(current);
  return Status::Ok();
}

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::marginalizePlan(const MargPlan& plan, bool keyframe_event,
                                                       FrameResult* result) {
  std::optional<MargPrior<Scalar>> before;
  if (marg_observer_) before = window_.prior;
  const auto t0 = Clock::now();
  Status status = marginalizer_->marginalize(window_, plan, &window_.prior, nullptr);
  result->t_marg_s = secondsSince(t0);
  if (!status.ok()) return status;
  if (marg_observer_) marg_observer_(window_, plan, *before, window_.prior);
  window_.dropMarginalizedFactors(plan);
  window_.fixFirstEstimates();
  if (keyframe_event && policy_.keepsLandmarks(window_)) {
    SparsifyEvent event;
    event.t_schur_s = result->t_marg_s;
    if (config_.marg_strategy == MargStrategy::kNfr) {
      sparsifyPrior(window_, config_.nfr_topology, config_.nfr_rigid_deflation, &event);
      result->t_marg_s += event.t_recovery_s + event.t_insert_s;
    } else {
      describeBlanket(window_, &event);
    }
    result->sparsify_event = std::move(event);
  }
  // The gauge diagnostics analyse a prior over frame states (the shadow prior of discard).
  if (reporting_.shadow_prior && !policy_.keepsLandmarks(window_)) {
    if (Status s = marginalizeShadow(plan, result); !s.ok()) return s;
  }
  window_.removeMarginalized(plan);
  return Status::Ok();
}

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::marginalizeShadow(const MargPlan& plan,
                                                         FrameResult* result) {
  const auto t1 = Clock::now();
  int shadow_rank = -1;
  Status status = marginalizer_->marginalize(window_, plan, &shadow_prior_, &shadow_rank);
  if (!status.ok()) return status;
  MargEvent event = shadowEvent();
  event.qr_rank = shadow_rank;
  event.n_marg_frames =
      static_cast<int>(std::count_if(plan.vars.begin(), plan.vars.end(), [](const VarKey& var) {
        return var.block == StateBlock::kPose;
      }));
  event.n_marg_landmarks = static_cast<int>(plan.landmarks.size());
  event.t_shadow_s = secondsSince(t1);
  result->marg_event = std::move(event);
  return Status::Ok();
}

template <typename Scalar>
MargEvent SlidingWindowEstimator<Scalar>::shadowEvent() const {
  MargEvent event;
  shadow_prior_.gaugeLayout(&event.layout, &event.state);
  // Gauge directions at the linearization points: the prior's nullspace lies there (FEJ).
  const VecX<Scalar> delta = window_.priorDelta(shadow_prior_);
  if (sqrtStorage(shadow_prior_.storage)) {
    MatX<Scalar> J;
    VecX<Scalar> r;
    shadow_prior_.sqrtRows(delta, &J, &r);
    event.J_m = J.template cast<double>();
    event.r_m = r.template cast<double>();
    event.H_m = event.J_m.transpose() * event.J_m;
    event.b_m = event.J_m.transpose() * event.r_m;
  } else {
    MatX<Scalar> H;
    VecX<Scalar> b;
    shadow_prior_.linearize(delta, &H, &b);
    event.H_m = H.template cast<double>();
    event.b_m = b.template cast<double>();
  }
  event.prior_rows = shadow_prior_.rows();
  return event;
}

#define MARGLAB_INST(S) template class SlidingWindowEstimator<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
