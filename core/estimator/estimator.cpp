#include "core/estimator/estimator.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/common/error.h"
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
SlidingWindowEstimator<Scalar>::SlidingWindowEstimator(const EstimatorSettings& config,
                                                       const Variant& variant,
                                                       const StereoRig<double>& rig,
                                                       const SE3<double>& T_w_i_initial,
                                                       std::optional<ImuSetup> imu,
                                                       EstimatorReporting reporting)
    : config_(config),
      reporting_(reporting),
      variant_(variant),
      window_(config, rig, std::move(imu)),
      policy_(config_),
      marginalizer_(makeMarginalizer<Scalar>(
          variant.marg, withPsdHessianPrior(variant.storage, config.psd_hessian_prior), config)),
      last_pose_(window_.isVio() ? window_.imu()->initial.T_w_i : T_w_i_initial),
      lambda_(static_cast<Scalar>(config.lambda_init)) {
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
  result.status = optimize(&result);
  result.t_opt_s = secondsSince(t0);
  if (capture_next_) {
    recordStep(result, &*captured_);
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
  const ImuPreintegration<double> pre = preintegrate<double>(
      imu.imu, s_i.t_ns, t_ns, s_i.b_g, s_i.b_a,
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
    const ImuState<Scalar> s_j = predictState<Scalar>(
        window_.stateOf(previous, StateAt::kCurrent), window_.imu_links.at(previous).factor.preintegration(),
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
  const int n = static_cast<int>(weights.size());
  const int m = static_cast<int>((weights.array() > 0).count());
  MargPrior<Scalar>& prior = window_.prior;
  prior.blocks.clear();
  prior.addBlock({frame_id, StateBlock::kPose}, first.T_w_i, first.speed_bias);
  if (first.has_speed_bias) {
    prior.addBlock({frame_id, StateBlock::kSpeedBias}, first.T_w_i, first.speed_bias);
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
// Levenberg–Marquardt

template <typename Scalar>
std::unique_ptr<Linearization<Scalar>> SlidingWindowEstimator<Scalar>::makeVariantLinearization()
    const {
  typename Linearization<Scalar>::Options options;
  options.damp_landmarks = config_.lm_landmark_damping;
  options.lambda_min = static_cast<Scalar>(config_.lambda_min);
  options.preconditioning = preconditioningOf(variant_.storage);
  return makeLinearization<Scalar>(variant_, options);
}

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::optimize(FrameResult* result) {
  // λ restarts at its initial value for every frame (as Basalt's optimize does).
  lambda_ = static_cast<Scalar>(config_.lambda_init);
  nu_ = Scalar(2);
  Scalar cost = window_.totalCost();
  result->cost_initial = static_cast<double>(cost);
  if (!std::isfinite(cost)) {
    return Status::Error(Status::Code::kNotFinite, "the cost of the window is not finite");
  }
  // Basalt counts every cost evaluation (`it <= vio_max_iterations`), rejected λ trials too.
  const bool basalt = config_.lm_stop_rule == LmStopRule::kBasalt;
  evaluations_left_ = basalt ? config_.lm_max_iterations + 1 : std::numeric_limits<int>::max();
  const int max_linearizations = basalt ? evaluations_left_ : config_.lm_max_iterations;
  const std::unique_ptr<Linearization<Scalar>> lin = makeVariantLinearization();
  for (int it = 0; it < max_linearizations; ++it) {
    lin->linearize(window_);
    if (Status s = lin->eliminate(); !s.ok()) return s;
    bool stop = false;
    if (Status s = lmIteration(*lin, &cost, &stop); !s.ok()) return s;
    ++result->lm_iterations;
    if (stop) break;
  }
  result->cost_final = static_cast<double>(cost);
  return checkFinite();
}

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::lmIteration(Linearization<Scalar>& lin, Scalar* cost,
                                                   bool* stop) {
  const Scalar lambda_min = static_cast<Scalar>(config_.lambda_min);
  const Scalar lambda_max = static_cast<Scalar>(config_.lambda_max);
  while (true) {
    LinearStep<Scalar> step;
    if (Status status = lin.solve(lambda_, &step); !status.ok()) {
      if (++failed_solves_ >= config_.max_failed_solves) {
        return Status::Error(status.code(), fmt::format("linear solve failed {} times in a row: {}",
                                                        failed_solves_, status.message()));
      }
      increaseDamping();
      continue;
    }
    failed_solves_ = 0;
    StepBackup backup;
    const Scalar max_step = applyStep(lin, step, &backup);
    const Scalar new_cost = window_.totalCost();
    --evaluations_left_;
    if (std::isfinite(new_cost) && new_cost < *cost) {
      const Scalar model_change = step.model_change;
      const Scalar rho = model_change < 0 ? (*cost - new_cost) / -model_change : Scalar(1);
      const Scalar f = Scalar(2) * rho - Scalar(1);
      lambda_ *= std::max(Scalar(1) / Scalar(3), Scalar(1) - f * f * f);
      lambda_ = std::clamp(lambda_, lambda_min, lambda_max);
      nu_ = Scalar(2);
      *stop = converged(*cost, new_cost, max_step);
      *cost = new_cost;
      return Status::Ok();
    }
    undoStep(lin, std::move(backup));
    // No decrease even with maximal damping (converged as far as LM can tell), or the evaluation
    // budget of the basalt rule spent.
    if (lambda_ >= lambda_max || evaluations_left_ <= 0) {
      *stop = true;
      return Status::Ok();
    }
    increaseDamping();
  }
}

template <typename Scalar>
bool SlidingWindowEstimator<Scalar>::converged(Scalar cost, Scalar new_cost,
                                               Scalar max_step) const {
  const bool small_step = max_step < static_cast<Scalar>(config_.stop_max_step);
  if (config_.lm_stop_rule == LmStopRule::kBasalt) {
    return cost - new_cost < static_cast<Scalar>(kBasaltStopCost) || small_step ||
           evaluations_left_ <= 0;
  }
  const Scalar relative_decrease = (cost - new_cost) / cost;
  return relative_decrease < static_cast<Scalar>(config_.stop_relative_cost) || small_step;
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::increaseDamping() {
  lambda_ = std::min(lambda_ * nu_, static_cast<Scalar>(config_.lambda_max));
  nu_ *= Scalar(2);
}

template <typename Scalar>
Scalar SlidingWindowEstimator<Scalar>::applyStep(const Linearization<Scalar>& lin,
                                                 const LinearStep<Scalar>& step,
                                                 StepBackup* backup) {
  const ColumnMap& column_of = lin.columns();
  const VecX<Scalar>& delta = step.delta;
  backup->frames = window_.frames;
  for (auto& [id, frame] : window_.frames) {
    frame.T_w_i = boxPlus<Scalar>(
        frame.T_w_i, delta.template segment<kPoseDim>(column_of.at({id, StateBlock::kPose})));
    if (frame.has_speed_bias) {
      frame.speed_bias +=
          delta.template segment<kSpeedBiasDim>(column_of.at({id, StateBlock::kSpeedBias}));
    }
  }
  const std::vector<LandmarkJacobians<Scalar>>& lins = lin.landmarks();
  backup->params.resize(lins.size());
  Scalar max_step = delta.size() ? delta.cwiseAbs().maxCoeff() : Scalar(0);
  for (size_t l = 0; l < lins.size(); ++l) {
    Landmark& lm = window_.landmarks.at(lins[l].track_id);
    backup->params[l] = lm.param;
    lm.param += step.delta_l[l];
    if (!lm.world()) lm.param.z() = std::max(lm.param.z(), Scalar(0));
    max_step = std::max(max_step, step.delta_l[l].cwiseAbs().maxCoeff());
  }
  for (int64_t track : window_.priorLandmarks()) {
    Vec3S& p_w = window_.landmarks.at(track).param;
    backup->reduced[track] = p_w;
    p_w += delta.template segment<kPointDim>(column_of.at({track, StateBlock::kLandmark}));
  }
  return max_step;
}

template <typename Scalar>
void SlidingWindowEstimator<Scalar>::undoStep(const Linearization<Scalar>& lin,
                                              StepBackup&& backup) {
  window_.frames = std::move(backup.frames);
  const std::vector<LandmarkJacobians<Scalar>>& lins = lin.landmarks();
  for (size_t l = 0; l < lins.size(); ++l) {
    window_.landmarks.at(lins[l].track_id).param = backup.params[l];
  }
  for (const auto& [track, p_w] : backup.reduced) window_.landmarks.at(track).param = p_w;
}

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::checkFinite() const {
  for (const auto& [id, frame] : window_.frames) {
    if (!frame.T_w_i.translation().allFinite() ||
        !frame.T_w_i.unitQuaternion().coeffs().allFinite() || !frame.speed_bias.allFinite()) {
      return Status::Error(Status::Code::kNotFinite, "a state turned non-finite");
    }
  }
  return Status::Ok();
}

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::computeStep(OptElimination elimination, Scalar lambda,
                                                   VecX<Scalar>* delta) const {
  typename Linearization<Scalar>::Options options;
  options.damp_landmarks = true;
  options.lambda_min = static_cast<Scalar>(config_.lambda_min);
  const std::unique_ptr<Linearization<Scalar>> lin =
      makeLinearization<Scalar>(elimination, options);
  lin->linearize(window_);
  if (Status s = lin->eliminate(); !s.ok()) return s;
  LinearStep<Scalar> step;
  const Status s = lin->solve(lambda, &step);
  *delta = std::move(step.delta);
  return s;
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
void SlidingWindowEstimator<Scalar>::recordStep(const FrameResult& result,
                                                WindowSnapshot* window) const {
  const WindowSnapshot now = snapshot();
  WindowSnapshot::Step& step = window->after;
  step.present = true;
  step.lm_iterations = result.lm_iterations;
  step.cost_initial = result.cost_initial;
  step.cost_final = result.cost_final;
  step.frames = now.frames;
  step.landmarks = now.landmarks;
  for (auto& lm : step.landmarks) lm.obs.clear();
}

template <typename Scalar>
WindowSnapshot SlidingWindowEstimator<Scalar>::snapshot() const {
  WindowSnapshot w = snapshotOf(window_);
  w.variant = variant_.name();
  w.config = config_;
  w.failed_solves = failed_solves_;
  return w;
}

template <typename Scalar>
SlidingWindowEstimator<Scalar> SlidingWindowEstimator<Scalar>::fromSnapshot(
    const WindowSnapshot& w, const Variant& variant, const std::optional<EstimatorSettings>& config) {
  if (w.frames.empty()) throw InputError("", 0, "window: no frames");
  EstimatorReporting reporting;
  reporting.shadow_prior = false;  // a restored window has no shadow prior
  SlidingWindowEstimator est(config ? *config : w.config, variant, w.rig, w.frames.front().T_w_i,
                             imuSetupOf<Scalar>(w), reporting);
  restoreWindow(w, variant.storage, &est.window_);
  for (const auto& fs : w.frames) {
    if (fs.is_keyframe) est.last_keyframe_ = std::max(est.last_keyframe_, fs.id);
    est.next_frame_index_ = std::max(est.next_frame_index_, fs.id + 1);
  }
  est.failed_solves_ = w.failed_solves;
  return est;
}

// ---------------------------------------------------------------------------------------------
// Marginalization

template <typename Scalar>
std::optional<MargPlan> SlidingWindowEstimator<Scalar>::planStateMarginalization(bool force) const {
  return policy_.stateMarginalization(window_, force);
}

template <typename Scalar>
MargPlan SlidingWindowEstimator<Scalar>::planKeyframeMarginalization(int64_t frame_id) const {
  return policy_.keyframeMarginalization(window_, frame_id);
}

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
  const auto t0 = Clock::now();
  Status status = marginalizer_->marginalize(window_, plan, &window_.prior, nullptr);
  result->t_marg_s = secondsSince(t0);
  if (!status.ok()) return status;
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

template <typename Scalar>
Status SlidingWindowEstimator<Scalar>::trialMarginalization(const MargPlan& plan, MargMethod method,
                                                            MatXd* H_m) const {
  MargPrior<Scalar> prior = shadow_prior_;
  // qr: the plain square root it produces; sc: the plain Hessian (with the config's psd alias).
  const PriorStorage storage =
      method == MargMethod::kQr
          ? PriorStorage{}
          : withPsdHessianPrior({Representation::kHessian}, config_.psd_hessian_prior);
  if (method == MargMethod::kQr && hessianStorage(prior.storage) && !prior.empty()) {
    return Status::Error(Status::Code::kInvalidArgument,
                         "qr marginalization needs a square-root shadow prior");
  }
  Status s = makeMarginalizer<Scalar>(method, storage, config_)
                 ->marginalize(window_, plan, &prior, nullptr);
  if (!s.ok()) return s;
  if (sqrtStorage(storage)) {
    MatX<Scalar> J;
    VecX<Scalar> r;
    prior.sqrtRows(VecX<Scalar>::Zero(prior.cols()), &J, &r);
    const MatXd J_d = J.template cast<double>();
    *H_m = J_d.transpose() * J_d;
  } else {
    *H_m = prior.hessianAtAnchor().template cast<double>();
  }
  return Status::Ok();
}

#define MARGLAB_INST(S) template class SlidingWindowEstimator<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
