#pragma once
// The sliding-window estimator of the paper (Demmel et al., ICCV 2021, §3–5; numbers of DESIGN §3)
// for stereo visual odometry (VO) and visual-inertial odometry (VIO): one template for every
// variant. The Variant picks landmark elimination (ns|sc), marginalization (qr|sc) and prior
// storage (sqrt|sq); Scalar is the precision of everything inside.
//
// State. Frames carry a pose T_w_i: the body (IMU) for VIO, the left camera for VO (then
// T_i_c0 = I). VIO states — the latest max_states frames — also carry a speed-bias block
// (v_w, b_g, b_a); older keyframes keep their pose only, up to max_kfs keyframes. Increments:
// pose δ = [δt; δφ], t ← t + δt, R ← exp(δφ) R; speed-bias additive (core/imu/imu_state.h).
// Landmarks hosted in a keyframe as ℓ = (u, v, ρ): stereographic bearing and inverse distance in
// the host's cam0, ρ clamped ≥ 0.
//
// Energy. E(x) = Σ_obs ρ_H(‖π_c(T_ct_h ℓ) − z‖) / σ² + Σ_k ½‖W r_imu,k‖² + ½‖r_rw,k‖² + E_m(x):
// Huber norm ρ_H (threshold huber_px) of the reprojection error of every observation (cam0 and
// cam1), σ = obs_std_px, linearized with IRLS weights √w/σ on the rows; for VIO the IMU
// preintegration residual between consecutive states (9 rows, whitened by the preintegrated
// covariance) and the bias random walk (6 rows, core/imu/imu_factor.h); the marginalization prior
// (marg_prior.h).
//
// Optimization (per frame). Levenberg–Marquardt, at most lm_max_iterations linearizations:
// landmarks are eliminated per landmark (LandmarkBlockNs or LandmarkBlockSc), the reduced system
// with the IMU terms and the prior is damped H_ii += max(λH_ii, λ_min) (landmarks alike) and
// solved by LDLT; the gain ratio ρ = actual / model decrease updates λ ← λ·max(1/3, 1 − (2ρ − 1)³)
// on success, λ ← λν, ν ← 2ν on failure. Stop on relative decrease < stop_relative_cost or
// max|δ| < stop_max_step.
//
// First-estimate Jacobians. A variable in the prior keeps its linearization point: reprojection
// and IMU Jacobians are evaluated there (residuals at the current estimate), which keeps the
// prior's nullspace consistent with the other terms.
//
// Marginalization (after each frame), one event combining:
//   VO   — a non-keyframe current frame is removed with its observations;
//   VIO  — when there are more than max_states states, the oldest goes: a keyframe loses its
//          speed-bias block (its pose stays), a non-keyframe its whole state (its observations are
//          dropped); the IMU factor leaving it joins the prior;
//   both — when there are more than max_kfs keyframes one pose-only keyframe is marginalized (the
//          oldest of all but the newest two with a share < marg_connected_share of its landmarks
//          still observed, else the DSO distance score) with the landmarks it hosts (its
//          observations of other landmarks are dropped); landmarks whose track ended are
//          marginalized right away.
// `qr`: landmarks by nullspace projection, then the flat QR of [marg | keep] on the stacked Q2ᵀ
// rows, IMU rows and prior rows (paper §4.2). `sc`: Schur complement of the landmarks, then of the
// marginalized blocks on the Hessian with a pseudo-inverse (eqs. 22–23), stored as (H̃, b̃) or
// LDLT-factorized.
//
// Gauge. The initial prior fixes the gauge: VO all 6 dof of the first pose (gauge_prior_weight);
// VIO position and yaw of the first state (gauge_prior_weight) and its biases (gauge_prior_bg,
// gauge_prior_ba) — gravity makes roll and pitch observable.
//
// Diagnostics. A shadow prior starts empty (no gauge prior) and is marginalized with the identical
// procedure, in the same precision (as Basalt does); its Hessian, in double, is what the paper's
// Figs. 1, 4–6 analyse. Its cost is timed separately from t_marg.

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/common/status.h"
#include "core/common/thread_pool.h"
#include "core/data/types.h"
#include "core/diagnostics/gauge.h"
#include "core/estimator/config.h"
#include "core/estimator/marg_prior.h"
#include "core/estimator/variant.h"
#include "core/geometry/camera.h"
#include "core/geometry/se3.h"
#include "core/imu/imu_factor.h"
#include "core/imu/imu_state.h"
#include "core/io/results_file.h"
#include "core/linalg/landmark_block.h"
#include "core/sim/tracks.h"
#include "core/sparsify/nfr.h"

namespace marglab {

// What a VIO estimator needs beyond the cameras: the IMU stream (synthetic or recorded, covering
// the frame times), its noise densities, gravity in the world, and the first state.
struct ImuSetup {
  ImuData imu;
  ImuNoise noise;
  double sample_period_s = 0.005;
  Eigen::Vector3d g_w = Eigen::Vector3d(0, 0, -9.81);
  ImuState<double> initial;  // T_w_i, v_w, b_g, b_a of the first frame
};

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

// One keyframe marginalization of a dense / nfr run: the /sparsify row of the results file (its
// frame_index and t_ns are the run's to fill) and, when nfr kept the dense prior, why.
struct SparsifyEvent : SparsifyRecord {
  std::string fallback_reason;
};

struct FrameResult {
  int64_t t_ns = 0;
  bool is_keyframe = false;
  int n_landmarks = 0;
  int n_observations = 0;
  int lm_iterations = 0;
  double cost_initial = 0;
  double cost_final = 0;
  double t_opt_s = 0;
  double t_marg_s = 0;
  SE3<double> T_w_i;  // body (VIO) or cam0 (VO) pose of the frame after optimization
  Eigen::Vector3d v_w = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  std::optional<MargEvent> marg_event;
  std::optional<SparsifyEvent> sparsify_event;
  Status status;  // not ok: the run failed at this frame
};

// One window of the estimator as optimize() reads it, in double (exact for f32 and f64 states),
// for replaying and benchmarking one optimization step outside a run (core/bench/window_io.h
// serializes it). IMU factors are kept as their inputs — the IMU samples around the window and each
// factor's time span and linearization biases — and preintegrated again on restore (deterministic,
// so the factor is the same). `after` holds the step the estimator took from this state.
struct WindowSnapshot {
  struct FrameState {
    int64_t id = 0, t_ns = 0;
    bool is_keyframe = false, linearized = false, has_speed_bias = false;
    bool speed_bias_linearized = false;
    SE3<double> T_w_i, T_w_i_lin;
    Vec<double, 9> speed_bias = Vec<double, 9>::Zero(), speed_bias_lin = Vec<double, 9>::Zero();
  };
  struct ObservationState {
    int64_t frame = 0;
    Eigen::Vector2d uv0 = Eigen::Vector2d::Zero(), uv1 = Eigen::Vector2d::Zero();
    bool has_right = false;
  };
  struct LandmarkState {
    int64_t id = 0, host = 0;
    Eigen::Vector3d param = Eigen::Vector3d::Zero();
    std::vector<ObservationState> obs;
  };
  struct ImuLinkState {
    int64_t from = 0, to = 0;
    Eigen::Vector3d bias_gyro_lin = Eigen::Vector3d::Zero(),
                    bias_accel_lin = Eigen::Vector3d::Zero();
  };
  struct PriorBlockState {
    VarKey var;
    int offset = 0;
    SE3<double> T0;
    Vec<double, 9> sb0 = Vec<double, 9>::Zero();
  };
  // The step from this state: optimize()'s outcome and the states after it.
  struct Step {
    bool present = false;
    int lm_iterations = 0;
    double cost_initial = 0, cost_final = 0;
    std::vector<FrameState> frames;        // T_w_i and speed_bias after the step
    std::vector<LandmarkState> landmarks;  // param after the step (no observations)
  };
  // Provenance (informational).
  std::string dataset, variant;
  int64_t frame_index = -1;  // index of the newest frame in the run
  // Setup.
  EstimatorConfig config;
  StereoRig<double> rig;
  bool vio = false;
  ImuNoise imu_noise;
  double imu_sample_period_s = 0.005;
  Eigen::Vector3d g_w = Eigen::Vector3d::Zero();
  ImuData imu;  // the samples the window's IMU factors integrate
  // State.
  int failed_solves = 0;
  std::vector<FrameState> frames;
  std::vector<LandmarkState> landmarks;
  std::vector<ImuLinkState> imu_links;
  PriorStorage prior_storage = PriorStorage::kSqrt;
  std::vector<PriorBlockState> prior_blocks;
  MatXd prior_J, prior_H;
  VecXd prior_r, prior_b;
  double prior_c = 0;
  Step after;
  int numObservations() const;
};

// What one marginalization removes: variables (frame blocks, and landmarks of a dense prior),
// landmarks eliminated with all their observations, the IMU factors starting at the listed
// frames, the observations in drop_obs_frames, and — strategies dense / nfr — the observations
// (track, frame) whose landmark stays as a variable of the new prior. Recovered (nfr) factors on
// marginalized variables are always included.
struct MargPlan {
  std::set<VarKey> vars;
  std::vector<int64_t> landmarks;
  std::vector<int64_t> imu_links;
  std::set<int64_t> drop_obs_frames;
  std::vector<std::pair<int64_t, int64_t>> kept_landmark_obs;
  bool empty() const {
    return vars.empty() && landmarks.empty() && imu_links.empty() && kept_landmark_obs.empty();
  }
};

template <typename Scalar>
class SlidingWindowEstimator {
 public:
  using SE3S = SE3<Scalar>;
  using Vec2S = Vec<Scalar, 2>;
  using Vec3S = Vec3<Scalar>;
  using Vec9S = Vec<Scalar, kSpeedBiasDim>;

  // VO: T_w_i_initial is the first cam0 pose (the rig's T_i_c0 is ignored: body = cam0).
  // VIO (imu given): the first state is imu->initial; the rig's extrinsics map body to cameras.
  SlidingWindowEstimator(const EstimatorConfig& config, const Variant& variant,
                         const StereoRig<double>& rig, const SE3<double>& T_w_i_initial,
                         std::optional<ImuSetup> imu = std::nullopt);

  // Throws InputError when a VIO frame lies outside the IMU stream.
  FrameResult processFrame(const TrackFrame& frame);

  bool isVio() const { return imu_.has_value(); }
  int numKeyframes() const;
  int numLandmarks() const { return static_cast<int>(landmarks_.size()); }
  const MargPrior<Scalar>& prior() const { return prior_; }
  const MargPrior<Scalar>& shadowPrior() const { return shadow_prior_; }
  std::vector<int64_t> keyframeIds() const;
  std::vector<int64_t> stateIds() const;  // frames with a speed-bias block (VIO)
  bool isKeyframe(int64_t frame_id) const { return frames_.at(frame_id).is_keyframe; }

  // Window capture: the next processFrame() stores its window right before optimizing, with the
  // step optimize() took (takeCapturedWindow() hands it over once).
  void captureNextWindow() { capture_next_ = true; }
  std::optional<WindowSnapshot> takeCapturedWindow();
  WindowSnapshot snapshot() const;
  // The estimator of a captured window, in this Scalar and the given variant (precision aside);
  // `config` replaces the captured one when given. Throws InputError on an inconsistent window.
  static SlidingWindowEstimator fromSnapshot(const WindowSnapshot& window, const Variant& variant,
                                             const std::optional<EstimatorConfig>& config = {});
  // One optimize() of the window as processFrame() runs it (LM iterations until a stop rule).
  Status optimizeWindow(FrameResult* result) { return optimize(result); }
  // Fills window->after from the current state (after optimizeWindow()).
  void recordStep(const FrameResult& result, WindowSnapshot* window) const;

  // Linearizes the current window and returns the LM step of all variables (layout: frames in id
  // order, pose then speed-bias) for damping λ with the given elimination (equivalence tests).
  Status computeStep(OptElimination elimination, Scalar lambda, VecX<Scalar>* delta) const;
  // The marginalization of the oldest VIO state (keyframe: its speed-bias; otherwise the whole
  // state), as the estimator would plan it now; nullopt for VO or with no state to spare.
  std::optional<MargPlan> planStateMarginalization(bool force = false) const;
  // The marginalization of keyframe `frame_id` with the landmarks it hosts.
  MargPlan planKeyframeMarginalization(int64_t frame_id) const;
  // The prior Hessian a plan would produce with `method` on a copy of the shadow prior (sqrt
  // storage for qr, Hessian for sc), in double (equivalence tests: qr vs sc).
  Status trialMarginalization(const MargPlan& plan, MargMethod method, MatXd* H_m) const;

 private:
  struct Frame {
    int64_t t_ns = 0;
    SE3S T_w_i;
    SE3S T_w_i_lin;
    bool linearized = false;  // pose in a prior: Jacobians at T_w_i_lin
    bool is_keyframe = false;
    bool has_speed_bias = false;
    Vec9S speed_bias = Vec9S::Zero();  // [v_w; b_g; b_a]
    Vec9S speed_bias_lin = Vec9S::Zero();
    bool speed_bias_linearized = false;
  };
  struct Observation {
    Vec2S uv0;
    bool has_right = false;
    Vec2S uv1;
  };
  // A factor recovered by nfr (core/sparsify/nfr.h), kept as the nonlinear residual
  // W (h(x) ⊟ z) of its variables: `frame`'s pose, velocity or bias (unary), or the pose of
  // `frame` and a landmark (pose–landmark). factor.spec indexes a blanket {variable, landmark}.
  struct NfrFactor {
    RecoveredFactor<Scalar> factor;
    BlanketKind kind = BlanketKind::kPose;  // of the unary variable (kPose for pose–landmark)
    int64_t frame = -1;
    // The window variable of frame it constrains (velocity and bias: the speed-bias block).
    VarKey var() const {
      return {frame, kind == BlanketKind::kPose ? StateBlock::kPose : StateBlock::kSpeedBias};
    }
  };
  struct Landmark {
    int64_t host = -1;  // < 0: a world point (strategies dense / nfr)
    Vec3S param;        // (u, v, ρ) in the host's cam0, or p_w
    std::map<int64_t, Observation> obs;
    bool linearized = false;  // in a dense prior: Jacobians at param_lin
    Vec3S param_lin = Vec3S::Zero();
    std::vector<NfrFactor> nfr;  // pose–landmark factors (one per nfr event that kept it)
    bool world() const { return host < 0; }
  };
  // One landmark linearized over the pose blocks of a system (frames mapped to columns).
  struct Linearized {
    int64_t track_id = -1;
    std::vector<int64_t> frames;  // local pose blocks
    MatX<Scalar> J_p;
    Mat<Scalar, Eigen::Dynamic, 3> J_l;
    VecX<Scalar> r;
    Scalar cost = 0;
  };
  // The IMU factor from frame `from` to frame `to` (consecutive states).
  struct ImuLink {
    int64_t to = -1;
    ImuFactor<Scalar> factor;
    Scalar dt_s = 0;
  };
  // An IMU factor linearized: 15 rows [W r_imu; r_rw] over [pose_i | sb_i | pose_j | sb_j].
  struct LinkLinearized {
    int64_t from = -1, to = -1;
    Mat<Scalar, 15, 30> J;
    Vec<Scalar, 15> r;
  };
  // Residual rows over a few variables of the window: J's columns are the variables' blocks at
  // the given offsets. The rows that enter the reduced system as they are (landmarks of a dense
  // prior, recovered unary factors) and the rows a marginalization stacks.
  struct RowBlock {
    std::vector<std::pair<VarKey, int>> vars;
    MatX<Scalar> J;
    VecX<Scalar> r;
  };
  using ColumnMap = std::map<VarKey, int>;
  // T_ct_h = (T_w_t T_i_ct)⁻¹ T_w_h T_i_c0 for every (host, target, camera) of the window, at the
  // current poses and (with Jacobians) at the first estimates: computed once per linearization
  // or cost evaluation instead of once per observation.
  struct RelativePoses {
    std::vector<int64_t> ids;  // frames in id order
    std::vector<SE3S> T_ct_h, T_ct_h_jac;
    std::vector<Mat<Scalar, 6, 6>> D_rel_h, D_rel_t;  // ⊞ Jacobians at the first estimates
    size_t index(int64_t host, int64_t target, int cam) const;
  };
  RelativePoses relativePoses(bool with_jacobians) const;

  Scalar landmarkCost(const Landmark& lm, const RelativePoses& rel) const;
  Scalar linkCost(int64_t from, const ImuLink& link) const;
  Scalar totalCost() const;
  // Returns false when the landmark has fewer than min_rows valid rows. The rows of its
  // pose–landmark factors (nfr) follow the observations' when with_nfr.
  bool linearizeLandmark(int64_t track_id, const Landmark& lm,
                         const std::set<int64_t>& system_frames, const RelativePoses& rel,
                         Linearized* out, bool with_nfr = true, int min_rows = 3) const;
  // The factor's variables (its frame's block, lm's point) at the current state or the first
  // estimates.
  Blanket<Scalar> nfrBlanket(const NfrFactor& f, const Landmark* lm, bool at_first_estimates) const;
  Scalar nfrCost(const NfrFactor& f, const Landmark* lm) const;
  // W (h(x) ⊟ z) at the current state and its Jacobian at the first estimates, over the factor's
  // variables (a velocity or bias factor spans its whole speed-bias block).
  void linearizeNfr(const NfrFactor& f, int64_t track_id, const Landmark* lm,
                    std::vector<std::pair<VarKey, int>>* vars, MatX<Scalar>* J,
                    VecX<Scalar>* r) const;
  // Landmarks of the prior (dense): reduced-system variables, not eliminated per landmark.
  std::set<int64_t> priorLandmarks() const;
  // A landmark's rows (observations in system_frames, its pose–landmark factor) with the landmark
  // as a variable; false when it has none.
  bool landmarkRows(int64_t track_id, const std::set<int64_t>& system_frames,
                    const RelativePoses& rel, bool with_nfr, RowBlock* out) const;
  // The rows the reduced system takes as they are: prior landmarks and recovered unary factors.
  std::vector<RowBlock> directRows(const std::set<int64_t>& system_frames,
                                   const RelativePoses& rel) const;
  // Keyframe marginalization with strategy dense / nfr: which landmarks stay (as world points),
  // which observations of kf join the prior.
  void planKeptLandmarks(int64_t kf, std::set<int64_t>* marg_landmarks, MargPlan* plan);
  // nfr: replaces prior_ by recovered factors (event gets the recovery's diagnostics); keeps it
  // dense when the recovery fails (event->fallback_reason).
  void sparsifyPrior(SparsifyEvent* event);
  // Size and non-zeros of prior_ as the blanket of a keyframe event; returns Λ_t.
  MatX<Scalar> describeBlanket(SparsifyEvent* event) const;
  // Strategy dense / nfr in effect (VIO only).
  bool keepsLandmarks() const {
    return imu_.has_value() && config_.marg_strategy != MargStrategy::kDiscard;
  }
  void linearizeLink(int64_t from, const ImuLink& link, LinkLinearized* out) const;
  PoseBlockMap blockMap(const Linearized& lin, const ColumnMap& column_of) const;
  // All variables of the window, frames in id order, pose then speed-bias; returns the size.
  int windowColumns(ColumnMap* column_of) const;
  VecX<Scalar> priorDelta(const MargPrior<Scalar>& prior) const;
  Status optimize(FrameResult* result);
  void addNewLandmarks(int64_t frame_id, const TrackFrame& frame);
  void initializeGaugePrior(int64_t frame_id);
  void addImuLink(int64_t from, int64_t to);
  std::optional<int64_t> selectKeyframeToMarginalize(int64_t current,
                                                     const std::set<VarKey>& marg_vars) const;
  Status marginalize(int64_t current, FrameResult* result);
  Vec3S jacobianPointOf(const Landmark& lm) const {
    return lm.linearized ? lm.param_lin : lm.param;
  }
  // Marginalizes the plan into `prior` with `method`.
  Status marginalizeInto(MargPrior<Scalar>& prior, MargMethod method, PriorStorage storage,
                         const MargPlan& plan, int* qr_rank) const;
  MargEvent shadowEvent() const;
  SE3S poseOf(int64_t frame_id) const { return frames_.at(frame_id).T_w_i; }
  Vec9S speedBiasOf(int64_t frame_id) const { return frames_.at(frame_id).speed_bias; }
  SE3S jacobianPoseOf(int64_t frame_id) const;
  ImuState<Scalar> stateOf(int64_t frame_id, bool at_linearization_point) const;

  // The IMU factor from `from` to `to`, preintegrated in double from the given biases.
  ImuLink makeImuLink(int64_t from, int64_t to, const Eigen::Vector3d& b_g,
                      const Eigen::Vector3d& b_a) const;

  EstimatorConfig config_;
  Variant variant_;
  StereoRig<double> rig_input_;  // as given (window capture)
  StereoRig<Scalar> rig_;
  std::array<SE3S, 2> T_i_c_;       // body to cam0 / cam1 (VO: I, T_c0_c1)
  std::array<SE3S, 2> T_c_h_host_;  // host cam0 to cam0 / cam1 of the same frame
  std::array<SE3S, 2> T_c_i_;       // T_i_c_ inverted (world-point landmarks)
  std::optional<ImuSetup> imu_;
  Vec3S g_w_ = Vec3S::Zero();
  std::map<int64_t, Frame> frames_;        // by frame index
  std::map<int64_t, Landmark> landmarks_;  // by track id
  std::map<int64_t, ImuLink> imu_links_;   // by start frame
  std::vector<NfrFactor> nfr_unary_;       // recovered unary factors (nfr)
  MargPrior<Scalar> prior_;
  MargPrior<Scalar> shadow_prior_;
  int64_t next_frame_index_ = 0;
  int64_t last_keyframe_ = -1;
  SE3<double> last_pose_;
  SE3<double> previous_pose_;
  bool has_previous_pose_ = false;
  Scalar lambda_;
  Scalar nu_ = Scalar(2);
  int failed_solves_ = 0;
  bool capture_next_ = false;
  std::optional<WindowSnapshot> captured_;
  // config_.lm_threads workers for optimize(); shared by copies of the estimator, which are never
  // optimized concurrently.
  std::shared_ptr<ThreadPool> pool_;

  // The benchmark suite times the phases of one LM iteration on captured windows.
  template <typename>
  friend class WindowKernels;
};

}  // namespace marglab
