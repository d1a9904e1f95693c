#pragma once
// Sliding-window stereo visual odometry (Demmel et al., ICCV 2021, §3–5; numbers of DESIGN §3),
// one template for every variant: the Variant picks landmark elimination (ns|sc), marginalization
// (qr|sc) and prior storage (sqrt|sq); Scalar is the precision of everything inside.
//
// State. Poses T_w_c of the left camera of up to max_kfs keyframes plus the current frame;
// increment δ = [δt; δφ], t ← t + δt, R ← exp(δφ) R. Landmarks hosted in a keyframe as
// ℓ = (u, v, ρ): stereographic bearing and inverse distance in the host camera, ρ clamped ≥ 0.
//
// Energy. E(x) = Σ_obs ρ_H(‖π_c(T_ct_h ℓ) − z‖) / σ² + E_m(x), the Huber norm ρ_H (threshold
// huber_px) of the reprojection error of every observation (cam0 and cam1) with σ = obs_std_px,
// linearized with IRLS weights √w/σ on the rows, plus the marginalization prior (marg_prior.h).
//
// Optimization (per frame). Levenberg–Marquardt, at most lm_max_iterations linearizations:
// landmarks are eliminated per landmark (LandmarkBlockNs or LandmarkBlockSc), the reduced camera
// system with the prior is damped H_ii += max(λH_ii, λ_min) (landmarks alike) and solved by
// LDLT; the gain ratio ρ = actual / model decrease updates λ ← λ·max(1/3, 1 − (2ρ − 1)³) on
// success, λ ← λν, ν ← 2ν on failure. Stop on relative decrease < stop_relative_cost or
// max|δ| < stop_max_step.
//
// First-estimate Jacobians. A frame in the prior keeps its linearization point T_w_c_lin: its
// reprojection Jacobians are evaluated there (residuals at the current estimate), which keeps
// the prior's nullspace consistent with the visual terms.
//
// Marginalization (after each frame). A non-keyframe current frame is removed with its
// observations; when there are more than max_kfs keyframes one is marginalized (the oldest of all
// but the newest two with a share < marg_connected_share of its landmarks still observed, else
// the DSO distance score) with the landmarks it hosts (its observations of other landmarks are
// dropped); landmarks whose track ended are marginalized right away. `qr`: landmarks by
// nullspace projection, then the flat QR of [marg | keep] on the stacked Q2ᵀ rows and prior rows
// (paper §4.2). `sc`: Schur complement of the landmarks, then of the frame poses on the Hessian
// with a pseudo-inverse (eqs. 22–23), stored as (H̃, b̃) or LDLT-factorized.
//
// Diagnostics. A shadow prior starts empty (no gauge prior) and is marginalized with the identical
// procedure, in the same precision (as Basalt does); its Hessian, in double, is what the paper's
// Figs. 1, 4–6 analyse. Its cost is timed separately from t_marg.

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/common/status.h"
#include "core/estimator/config.h"
#include "core/estimator/marg_prior.h"
#include "core/estimator/variant.h"
#include "core/geometry/camera.h"
#include "core/geometry/se3.h"
#include "core/linalg/landmark_block.h"
#include "core/sim/tracks.h"

namespace marglab {

// One marginalization event of the shadow (gauge-free) prior, in double, for diagnostics.
struct MargEvent {
  std::vector<int64_t> frame_ids;  // prior layout (6 dof per frame)
  std::vector<SE3<double>> T_w_c;  // linearization point of each layout frame
  MatXd H_m;                       // prior Hessian (J_mᵀJ_m formed in double for sqrt)
  VecXd b_m;                       // gradient at the current state
  MatXd J_m;                       // square-root storage only
  VecXd r_m;                       // square-root storage only, at the current state
  int prior_rows = 0;
  int qr_rank = -1;  // total rank revealed by the flat QR (−1 for sc)
  int n_marg_frames = 0;
  int n_marg_landmarks = 0;
  double t_shadow_s = 0;
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
  SE3<double> T_w_c;
  std::optional<MargEvent> marg_event;
  Status status;  // not ok: the run failed at this frame
};

template <typename Scalar>
class VoEstimator {
 public:
  using SE3S = SE3<Scalar>;
  using Vec2S = Vec<Scalar, 2>;
  using Vec3S = Vec3<Scalar>;
  static constexpr int kPoseDim = 6;

  // rig: cam0/cam1 intrinsics and extrinsics (T_i_c0 is ignored: the state is T_w_c0).
  VoEstimator(const EstimatorConfig& config, const Variant& variant, const StereoRig<double>& rig,
              const SE3<double>& T_w_c0_initial);

  FrameResult processFrame(const TrackFrame& frame);

  // Introspection for tests and window capture.
  int numKeyframes() const;
  int numLandmarks() const { return static_cast<int>(landmarks_.size()); }
  const MargPrior<Scalar>& prior() const { return prior_; }
  const MargPrior<Scalar>& shadowPrior() const { return shadow_prior_; }
  std::vector<int64_t> keyframeIds() const;
  // Linearizes the current window and returns the pose part of the LM step for damping λ with
  // the given elimination (equivalence tests: ns vs sc on the same window).
  Status computeStep(OptElimination elimination, Scalar lambda, VecX<Scalar>* delta_poses) const;
  // The prior that a marginalization of `frame_id` (with its hosted landmarks) would produce,
  // with `method`, on a copy of the current shadow prior (equivalence tests: qr vs sc).
  Status trialMarginalization(int64_t frame_id, MargMethod method, MatXd* H_m) const;

 private:
  struct Frame {
    int64_t t_ns = 0;
    SE3S T_w_c;
    SE3S T_w_c_lin;
    bool linearized = false;
    bool is_keyframe = false;
  };
  struct Observation {
    Vec2S uv0;
    bool has_right = false;
    Vec2S uv1;
  };
  struct Landmark {
    int64_t host = -1;
    Vec3S param;  // (u, v, ρ)
    std::map<int64_t, Observation> obs;
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

  Scalar landmarkCost(const Landmark& lm) const;
  Scalar totalCost() const;
  // Returns false when the landmark has fewer than 3 valid rows.
  bool linearizeLandmark(int64_t track_id, const Landmark& lm,
                         const std::set<int64_t>& system_frames, Linearized* out) const;
  PoseBlockMap blockMap(const Linearized& lin, const std::map<int64_t, int>& column_of) const;
  Status optimize(FrameResult* result);
  void addNewLandmarks(int64_t frame_id, const TrackFrame& frame);
  std::optional<int64_t> selectKeyframeToMarginalize(int64_t current) const;
  Status marginalize(int64_t current, FrameResult* result);
  // Marginalizes `marg_frames` and `marg_landmarks` into `prior` with `method`.
  Status marginalizeInto(MargPrior<Scalar>& prior, MargMethod method, PriorStorage storage,
                         const std::set<int64_t>& marg_frames,
                         const std::vector<int64_t>& marg_landmarks, int* qr_rank) const;
  SE3S poseOf(int64_t frame_id) const { return frames_.at(frame_id).T_w_c; }
  SE3S jacobianPoseOf(int64_t frame_id) const;

  EstimatorConfig config_;
  Variant variant_;
  StereoRig<Scalar> rig_;
  SE3S T_c0_c1_;
  std::map<int64_t, Frame> frames_;        // by frame index
  std::map<int64_t, Landmark> landmarks_;  // by track id
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
};

}  // namespace marglab
