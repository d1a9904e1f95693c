#pragma once
// The sliding-window estimator of the paper (Demmel et al., ICCV 2021, §3–5; numbers of
// docs/design.md §3) for stereo visual odometry (VO) and visual-inertial odometry (VIO): one
// template for every variant. The Variant picks landmark elimination (ns|sc), marginalization
// (qr|sc) and prior storage (variant.h); Scalar is the precision of the state (mixed: double, with
// the landmarks eliminated in float).
//
// The estimator keeps the window (window.h: variables, factors, their cost and linearization) and
// decides what happens to it frame by frame; its collaborators do the numerics (module map:
// docs/design.md §1): the optimizer (levenberg_marquardt.h), the marginalization policy and the
// marginalizer.
//
// State. VIO states — the latest max_states frames — carry a speed-bias block (v_w, b_g, b_a);
// older keyframes keep their pose only, up to max_kfs keyframes. Increments: pose
// δ = [δt; δφ], t ← t + δt, R ← exp(δφ) R; speed-bias additive (core/imu/imu_state.h); hosted
// landmarks additive with ρ clamped ≥ 0.
//
// Optimization (per frame): Levenberg–Marquardt on the window through the variant's Linearization
// (levenberg_marquardt.h: the model, the damping rule, the stop rules).
//
// First-estimate Jacobians. A variable in the prior keeps its linearization point: reprojection
// and IMU Jacobians are evaluated there (residuals at the current estimate), which keeps the
// prior's nullspace consistent with the other terms.
//
// Marginalization (after each frame): the policy (marg_policy.h) plans what leaves the window.
// The variant's Marginalizer (marginalizer.h) carries it out: `qr` by the flat QR of the stacked
// rows (paper §4.2), `sc` by the Schur complement on the Hessian (eqs. 22–23). Strategy nfr then
// replaces the prior by recovered factors (prior_sparsifier.h).
//
// Gauge. The initial prior fixes the gauge: VO all 6 dof of the first pose (gauge_prior_weight);
// VIO position and yaw of the first state (gauge.prior_weight) and its biases
// (gauge.prior_bias_gyro, gauge.prior_bias_accel) — gravity makes roll and pitch observable.
//
// Diagnostics. A shadow prior starts empty (no gauge prior) and is marginalized with the identical
// procedure, in the same precision (as Basalt does); its Hessian, in double, is what the paper's
// Figs. 1, 4–6 analyse. Its cost is timed separately from t_marg.

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/common/status.h"
#include "core/data/tracks.h"
#include "core/diagnostics/gauge.h"
#include "core/estimator/estimator_settings.h"
#include "core/estimator/levenberg_marquardt.h"
#include "core/estimator/marg_policy.h"
#include "core/estimator/marg_prior.h"
#include "core/estimator/marginalizer.h"
#include "core/estimator/prior_sparsifier.h"
#include "core/estimator/variant.h"
#include "core/estimator/window.h"
#include "core/estimator/window_snapshot.h"
#include "core/geometry/camera.h"
#include "core/geometry/se3.h"
#include "core/io/results_records.h"

namespace marglab {

// One marginalization event of the shadow (gauge-free) prior, in double, for diagnostics.
struct MargEvent {
  PriorLayout layout;  // pose / velocity / gyro-bias / accel-bias blocks of the prior
  GaugeState state;    // linearization points of the layout's poses and velocities
  MatXd H_m;           // prior Hessian (J_mᵀJ_m formed in double for sqrt)
  VecXd b_m;           // gradient at the current state
  MatXd J_m;           // square-root storage only
  VecXd r_m;           // square-root storage only, at the current state
  int prior_rows = 0;
  int qr_rank = -1;  // total rank revealed by the flat QR (−1 for sc)
  int n_marg_frames = 0;
  int n_marg_landmarks = 0;
  double t_shadow_s = 0;
  int numPoses() const;
};

// What the estimator reports of one frame: its /frames row (p_est, q_est: the body (VIO) or cam0
// (VO) pose after optimization; p_gt left to the run, which has the ground truth) and what the
// file does not store, or stores elsewhere.
struct FrameResult : FrameRecord {
  Eigen::Vector3d v_w = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  std::optional<MargEvent> marg_event;
  std::optional<SparsifyEvent> sparsify_event;
  Status status;  // not ok: the run failed at this frame
};

template <typename Scalar>
class SlidingWindowEstimator {
 public:
  using SE3S = SE3<Scalar>;
  using Vec3S = Vec3<Scalar>;
  using Frame = typename Window<Scalar>::Frame;
  using Landmark = typename Window<Scalar>::Landmark;

  // VO: T_w_i_initial is the first cam0 pose (the rig's T_i_c0 is ignored: body = cam0).
  // VIO (imu given): the first state is imu->initial; the rig's extrinsics map body to cameras.
  // config is used as given: the run validated it (prepareRun); min_frames_after_kf −1 (no
  // dataset default applied) spaces keyframes as 1 does. `reporting`: the shadow prior and the
  // consistency count (estimator_settings.h).
  SlidingWindowEstimator(const EstimatorSettings& config, const Variant& variant,
                         const StereoRig<double>& rig, const SE3<double>& T_w_i_initial,
                         std::optional<ImuSetup> imu = std::nullopt,
                         EstimatorReporting reporting = {});

  // Throws InputError when a VIO frame lies outside the IMU stream.
  FrameResult processFrame(const TrackFrame& frame);

  // Motion prediction for a front-end (core/frontend/motion_prediction.h; the run pipeline turns
  // it into the front-end's FramePrediction): the pose T_w_i a frame at t_ns starts from in
  // processFrame — VO constant velocity, VIO the newest state propagated through the IMU up to
  // t_ns (its biases kept) — and nullopt before the first frame. Throws InputError when a VIO t_ns
  // lies outside the IMU stream.
  std::optional<SE3<double>> predictPose(int64_t t_ns) const;
  // The newest frame's pose T_w_i (nullopt before the first frame).
  std::optional<SE3<double>> newestPose() const;
  // The window's landmark estimates p_w, by track id.
  std::vector<std::pair<int64_t, Eigen::Vector3d>> landmarkPoints() const;

  bool isVio() const { return window_.isVio(); }
  const Window<Scalar>& window() const { return window_; }
  int numLandmarks() const { return static_cast<int>(window_.landmarks.size()); }
  const MargPrior<Scalar>& prior() const { return window_.prior; }
  const MargPrior<Scalar>& shadowPrior() const { return shadow_prior_; }
  std::vector<int64_t> keyframeIds() const { return window_.keyframeIds(); }
  std::vector<int64_t> stateIds() const { return window_.stateIds(); }
  bool isKeyframe(int64_t frame_id) const { return window_.frames.at(frame_id).is_keyframe; }

  // Called after each marginalization of the window's prior, before the window drops what it
  // marginalized: the window as it was marginalized, the plan, the prior before and after (for
  // measuring the marginalization's rounding, marg_rounding.h). Unset (default): not called.
  using MargObserver =
      std::function<void(const Window<Scalar>&, const MargPlan&, const MargPrior<Scalar>& before,
                         const MargPrior<Scalar>& after)>;
  void setMargObserver(MargObserver observer) { marg_observer_ = std::move(observer); }

  // Window capture: the next processFrame() stores its window right before optimizing, with the
  // step the optimizer took (takeCapturedWindow() hands it over once).
  void captureNextWindow() { capture_next_ = true; }
  std::optional<WindowSnapshot> takeCapturedWindow();
  WindowSnapshot snapshot() const;
  // The estimator of a captured window, in this Scalar and the given variant (precision aside);
  // `config` replaces the captured one when given. Throws InputError on an inconsistent window.
  static SlidingWindowEstimator fromSnapshot(const WindowSnapshot& window, const Variant& variant,
                                             const std::optional<EstimatorSettings>& config = {});

 private:
  // Frame intake: the new frame's state (VIO: predicted through its IMU factor; VO: constant
  // velocity) and its observations of known landmarks; returns how many it observed.
  int addFrame(int64_t id, const TrackFrame& frame);
  void addNewLandmarks(int64_t frame_id, const TrackFrame& frame);
  void initializeGaugePrior(int64_t frame_id);
  void addImuLink(int64_t from, int64_t to);
  void updateKeyframe(int64_t id, const TrackFrame& frame, int connected);
  // result->n_checked / n_inconsistent of the optimized frame id (reporting_.inconsistent_px).
  void countInconsistent(int64_t id, FrameResult* result) const;

  // Marginalization after frame `current` (the policy's plan), of the shadow prior alike.
  Status marginalize(int64_t current, FrameResult* result);
  Status marginalizePlan(const MargPlan& plan, bool keyframe_event, FrameResult* result);
  Status marginalizeShadow(const MargPlan& plan, FrameResult* result);
  MargEvent shadowEvent() const;

  EstimatorSettings config_;
  EstimatorReporting reporting_;
  Variant variant_;
  Window<Scalar> window_;
  MargPrior<Scalar> shadow_prior_;
  MarginalizationPolicy<Scalar> policy_;
  std::shared_ptr<const Marginalizer<Scalar>> marginalizer_;
  int64_t next_frame_index_ = 0;
  int64_t last_keyframe_ = -1;
  SE3<double> last_pose_;
  SE3<double> previous_pose_;
  bool has_previous_pose_ = false;
  LevenbergMarquardt<Scalar> lm_;
  bool capture_next_ = false;
  std::optional<WindowSnapshot> captured_;
  MargObserver marg_observer_;
};

}  // namespace marglab
