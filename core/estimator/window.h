#pragma once
// The sliding window of the estimator: its variables, its factors, and their cost and
// linearization at the current state (docs/design.md §3). The estimator (estimator.h) decides what
// enters and leaves the window; the linearization (linearization.h) and the marginalizers
// (marginalizer.h) read it.
//
// Variables. Frames carry a pose T_w_i (the body for VIO, the left camera for VO) and — VIO, the
// latest states only — a speed-bias block [v_w; b_g; b_a]. Landmarks are hosted in a keyframe as
// ℓ = (u, v, ρ) in the host's cam0, or (strategies dense / nfr) world points p_w. A variable in the
// marginalization prior keeps its first estimate (…_lin), where all Jacobians are evaluated.
//
// Factors. E(x) = Σ_obs ρ_H(‖π(q) − z‖)/σ² (core/reprojection) + Σ_k ½‖W r_imu,k‖² + ½‖r_rw,k‖²
// (core/imu/imu_factor.h) + Σ recovered ½‖W (h(x) ⊟ z)‖² (core/sparsify, strategy nfr) + E_m(x)
// (marg_prior.h).
//
// Calibration. With [estimator] estimate_right_cx_offset the window has one more variable, the
// offset c (pixels) added to the right camera's cx: the rectified pair's disparity offset
// (docs/design.md §3, "The stereo cx offset"). Every right-camera row's u residual moves by
// ∂r_u/∂c = √w/σ; c lies in every marginalization prior from the first frame's gauge prior on
// (weight 1/σ_c²) and is never marginalized.
//
// Columns. The reduced system orders its variables as frames by id, pose then speed-bias, then the
// landmarks of a dense prior (they are not eliminated per landmark: the prior couples them), then
// the stereo offset (PoseBlockMap's extra column of every landmark block).

#include <algorithm>
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/common/thread_pool.h"
#include "core/data/types.h"
#include "core/estimator/estimator_settings.h"
#include "core/estimator/marg_prior.h"
#include "core/geometry/camera.h"
#include "core/geometry/se3.h"
#include "core/imu/imu_factor.h"
#include "core/imu/imu_state.h"
#include "core/reprojection/reprojection_factor.h"
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

// Residual rows over a few variables of the window: J's columns are the variables' blocks at the
// given offsets.
template <typename Scalar>
struct RowBlock {
  std::vector<std::pair<VarKey, int>> vars;
  MatX<Scalar> J;
  VecX<Scalar> r;
};

// An IMU factor linearized: 15 rows [W r_imu; r_rw] over [pose_i | sb_i | pose_j | sb_j].
template <typename Scalar>
struct LinkLinearized {
  int64_t from = -1, to = -1;
  Mat<Scalar, 15, 30> J;
  Vec<Scalar, 15> r;
  std::vector<std::pair<VarKey, int>> vars() const;
};

using ColumnMap = std::map<VarKey, int>;

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

// Where a frame's state is read: its current estimate, or its first estimate (the linearization
// point of the factors that reached the prior, FEJ).
enum class StateAt { kCurrent, kFirstEstimate };
// Relative poses with or without the first-estimate poses the Jacobians are taken at.
enum class WithJacobians { kNo, kYes };
// A landmark's rows with or without the recovered (nfr) factors on it.
enum class NfrRows { kExclude, kInclude };

template <typename Scalar>
class Window {
 public:
  using SE3S = SE3<Scalar>;
  using Vec2S = Vec<Scalar, 2>;
  using Vec3S = Vec3<Scalar>;
  using Vec9S = Vec<Scalar, kSpeedBiasDim>;

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
  // W (h(x) ⊟ z) of its variables: `frame`'s pose, velocity or bias (unary), the pose of `frame`
  // and a landmark (pose–landmark), or the poses of `frame` and `frame_b` (relative pose).
  // factor.spec indexes a blanket {variable, landmark} or {pose a, pose b}.
  struct NfrFactor {
    RecoveredFactor<Scalar> factor;
    BlanketKind kind = BlanketKind::kPose;  // of the unary variable (kPose for the others)
    int64_t frame = -1;
    int64_t frame_b = -1;  // relative pose: the second pose
    // The window variable of frame it constrains (velocity and bias: the speed-bias block).
    VarKey var() const {
      return {frame, kind == BlanketKind::kPose ? StateBlock::kPose : StateBlock::kSpeedBias};
    }
    bool relativePose() const { return factor.spec.kind == NfrFactorKind::kRelativePose; }
    // Whether it constrains a variable of vars (its landmark aside).
    bool touches(const std::set<VarKey>& vars) const {
      return vars.count(var()) != 0 ||
             (relativePose() && vars.count({frame_b, StateBlock::kPose}) != 0);
    }
  };
  // The unary pose and velocity factors of one nfr event with rigid deflation
  // (core/sparsify/rigid_deflation.h), kept together as ½‖A [e_1; …; e_k]‖², e_i their whitened
  // residuals. A couples them: a marginalization that takes one of their variables takes all.
  struct NfrJointFactor {
    std::vector<NfrFactor> members;
    MatX<Scalar> A;
    bool touches(const std::set<VarKey>& vars) const {
      return std::any_of(members.begin(), members.end(),
                         [&vars](const NfrFactor& f) { return f.touches(vars); });
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
    const Vec3S& jacobianPoint() const { return linearized ? param_lin : param; }
  };
  // The IMU factor from frame `from` to frame `to` (consecutive states).
  struct ImuLink {
    int64_t to = -1;
    ImuFactor<Scalar> factor;
    Scalar dt_s = 0;
  };
  // T_ct_h = (T_w_t T_i_ct)⁻¹ T_w_h T_i_c0 for every (host, target, camera) of the window, at the
  // current poses and (with Jacobians) at the first estimates: computed once per linearization
  // or cost evaluation instead of once per observation.
  struct RelativePoses {
    std::vector<int64_t> ids;  // frames in id order
    std::vector<SE3S> T_ct_h, T_ct_h_jac;
    std::vector<Mat<Scalar, 6, 6>> D_rel_h, D_rel_t;  // ⊞ Jacobians at the first estimates
    size_t index(int64_t host, int64_t target, int cam) const;
    // Entries by positions in ids. A landmark's observations come in frame order, so the cost
    // evaluation walks ids with a cursor (next) instead of a binary search per observation. (The
    // linearization, compiled per ISA, keeps index(): a change there moves the AVX rounding of
    // nfr runs through GCC's inlining.)
    size_t pos(int64_t frame) const;
    size_t at(size_t host_pos, size_t target_pos, int cam) const {
      return (host_pos * ids.size() + target_pos) * 2 + static_cast<size_t>(cam);
    }
    // The position of `frame`, searched forward from `from` (a frame at or after ids[from]).
    size_t next(int64_t frame, size_t from) const {
      while (from < ids.size() && ids[from] < frame) ++from;
      return from;
    }
  };

  // VO (no imu): the body is cam0 (T_i_c0 = I, cam1 at T_c0_c1). VIO: the rig's extrinsics.
  Window(const EstimatorSettings& config, const StereoRig<double>& rig,
         std::optional<ImuSetup> imu);

  // The variables and factors; the estimator and its collaborators edit them.
  std::map<int64_t, Frame> frames;        // by frame index
  std::map<int64_t, Landmark> landmarks;  // by track id
  std::map<int64_t, ImuLink> imu_links;   // by start frame
  std::vector<NfrFactor> nfr_states;      // recovered unary and relative-pose factors (nfr)
  std::vector<NfrJointFactor> nfr_joint;  // deflated unary factors (nfr_rigid_deflation)
  MargPrior<Scalar> prior;

  bool isVio() const { return imu_.has_value(); }
  const std::optional<ImuSetup>& imu() const { return imu_; }
  const StereoRig<double>& rigInput() const { return rig_input_; }
  // The rig at the current stereo offset (cam1's cx + c).
  const StereoRig<Scalar>& rig() const { return rig_; }
  bool estimatesStereoOffset() const { return config_.estimate_right_cx_offset; }
  Scalar stereoOffset() const { return stereo_offset_; }
  void setStereoOffset(Scalar c);
  const SE3S& T_i_c(int cam) const { return T_i_c_[cam]; }
  const EstimatorSettings& config() const { return config_; }
  // config_.lm_threads workers; shared by copies of the window, which are never evaluated
  // concurrently.
  ThreadPool& pool() const { return *pool_; }

  // Values at the current state or at the first estimates (Jacobians).
  SE3S poseOf(int64_t frame_id) const { return frames.at(frame_id).T_w_i; }
  Vec9S speedBiasOf(int64_t frame_id) const { return frames.at(frame_id).speed_bias; }
  SE3S jacobianPoseOf(int64_t frame_id) const;
  ImuState<Scalar> stateOf(int64_t frame_id, StateAt at) const;
  std::vector<int64_t> keyframeIds() const;
  std::vector<int64_t> stateIds() const;  // frames with a speed-bias block (VIO)

  // Landmarks of the prior (dense): reduced-system variables, not eliminated per landmark.
  std::set<int64_t> priorLandmarks() const;
  // All variables of the window in column order; returns the number of columns.
  int windowColumns(ColumnMap* column_of) const;
  // δ = x ⊟ x⁰ of a prior over this window's variables.
  VecX<Scalar> priorDelta(const MargPrior<Scalar>& prior) const;

  // Costs at the current state.
  RelativePoses relativePoses(WithJacobians jacobians) const;
  Scalar landmarkCost(const Landmark& lm, const RelativePoses& rel) const;
  Scalar linkCost(int64_t from, const ImuLink& link) const;
  Scalar nfrCost(const NfrFactor& f, const Landmark* lm) const;
  Scalar nfrJointCost(const NfrJointFactor& f) const;
  Scalar totalCost() const;
  // ‖π(q) − z‖ in pixels, cam0, at the current state, of frame_id's observations of landmarks it
  // shares with other frames and does not host; +∞ where q does not project (behind the camera).
  std::vector<Scalar> frameReprojectionErrors(int64_t frame_id) const;

  // One landmark's rows over the frames in system_frames (its pose–landmark factors after the
  // observations with NfrRows::kInclude). False when it has fewer than min_rows rows.
  bool linearizeLandmark(int64_t track_id, const Landmark& lm,
                         const std::set<int64_t>& system_frames, const RelativePoses& rel,
                         LandmarkJacobians<Scalar>* out, NfrRows nfr = NfrRows::kInclude,
                         int min_rows = 3) const;
  // The same rows with the landmark as a variable of the system; false when it has none.
  bool landmarkRows(int64_t track_id, const std::set<int64_t>& system_frames,
                    const RelativePoses& rel, NfrRows nfr, RowBlock<Scalar>* out) const;
  // The rows the reduced system takes as they are: prior landmarks and recovered state factors.
  std::vector<RowBlock<Scalar>> directRows(const std::set<int64_t>& system_frames,
                                           const RelativePoses& rel) const;
  // W (h(x) ⊟ z) of a recovered factor at the current state, its Jacobian at the first estimates
  // (a velocity or bias factor spans its whole speed-bias block).
  RowBlock<Scalar> linearizeNfr(const NfrFactor& f, int64_t track_id, const Landmark* lm) const;
  // A [W_i (h_i(x) ⊟ z_i)] stacked over the members, its Jacobian over their variables.
  RowBlock<Scalar> linearizeNfrJoint(const NfrJointFactor& f) const;
  LinkLinearized<Scalar> linearizeLink(int64_t from, const ImuLink& link) const;

  // After a marginalization of `plan`: its factors now in the prior go (observations of kept
  // landmarks, recovered factors on marginalized variables), the prior's variables keep their
  // first estimates, the marginalized variables leave.
  void dropMarginalizedFactors(const MargPlan& plan);
  void fixFirstEstimates();
  void removeMarginalized(const MargPlan& plan);

  // The IMU factor from `from` to `to`, preintegrated in double from the given biases.
  ImuLink makeImuLink(int64_t from, int64_t to, const Eigen::Vector3d& b_g,
                      const Eigen::Vector3d& b_a) const;

 private:
  // The factor's variables (its frame's block, lm's point) at the current state or the first
  // estimates.
  Blanket<Scalar> nfrBlanket(const NfrFactor& f, const Landmark* lm, bool at_first_estimates) const;
  // The observation rows of one landmark (no pose–landmark factors).
  void observationRows(const Landmark& lm, const std::set<int64_t>& system_frames,
                       const RelativePoses& rel, std::vector<ReprojectionRows<Scalar>>* rows,
                       Scalar* cost) const;

  EstimatorSettings config_;
  ReprojectionNoise<Scalar> noise_;
  StereoRig<double> rig_input_;  // as given (window capture)
  StereoRig<Scalar> rig_;
  Scalar stereo_offset_ = 0;
  std::array<SE3S, 2> T_i_c_;       // body to cam0 / cam1 (VO: I, T_c0_c1)
  std::array<SE3S, 2> T_c_h_host_;  // host cam0 to cam0 / cam1 of the same frame
  std::array<SE3S, 2> T_c_i_;       // T_i_c_ inverted (world-point landmarks)
  std::optional<ImuSetup> imu_;
  Vec3S g_w_ = Vec3S::Zero();
  std::shared_ptr<ThreadPool> pool_;
};

}  // namespace marglab
