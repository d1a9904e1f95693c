#pragma once
// The estimator's settings (docs/design.md §3): every number the sliding-window estimator uses,
// in one struct. The run's config (core/pipeline/run_config.h) holds them beside the pipeline's
// sections and reads and writes them all as one TOML table; a window file (window_io.h) records
// them alone.
//
// TOML layout (all keys optional; unknown keys are errors):
//   [window]        max_kfs, max_states
//   [residuals]     obs_std_px, huber_px
//   [gauge]         prior_weight (VO: 6 pose dof; VIO: position and yaw), prior_bias_gyro,
//                   prior_bias_accel (VIO: first state's biases)
//   [keyframes]     connected_ratio, min_frames_after_kf (−1: dataset default), min_baseline_m,
//                   marg_connected_share
//   [lm]            max_iterations, lambda_init, lambda_min, lambda_max, stop_relative_cost,
//                   stop_max_step, stop_rule ("marglab"|"basalt", see LmStopRule),
//                   max_failed_solves, indefinite_system ("fail"|"solve", see IndefiniteSystem),
//                   landmark_damping, threads
//   [marginalization] qr_threshold_mode ("absolute"|"relative"), qr_threshold (−1: √ε of the
//                   scalar type), strategy ("discard"|"dense"|"nfr", keyframe marginalization of
//                   VIO; see MargStrategy), nfr_topology ("paper"|"joint-states"|"relative-pose",
//                   see SparsifyTopology), nfr_rigid_deflation (true: nfr's unary factors lose
//                   their information in excess of the dense prior's along the window's rigid
//                   motions, core/sparsify/rigid_deflation.h; needs strategy "nfr" and
//                   nfr_topology "paper"), psd_hessian_prior (true: a Hessian prior — storages
//                   sq, sqp, sqj — is stored as the Hessian JᵀJ, Jᵀr of its clamped LDLT square
//                   root, positive semidefinite like a square-root prior; README item 5),
//                   lost_landmarks ("at-once"|"with-state", see LostLandmarkMarg)
//   [imu]           noise_profile ("kalibr"|"basalt": the IMU densities of VIO runs, for the
//                   synthetic IMU and the estimator's weights; see core/imu/noise_profile.h)
//   [estimator]     estimate_right_cx_offset (true: the right camera's cx offset is a window
//                   variable, window.h; strategy "discard" only), right_cx_offset_prior_px (its
//                   prior's σ in pixels)
//
// Validation (docs/design.md §9): every key has a range (estimatorBindings); the relations between
// keys (lambda_min ≤ lambda_init ≤ lambda_max; a relative qr_threshold below 1;
// nfr_rigid_deflation only with strategy nfr, topology paper) are estimatorRelationProblems. A
// violation is an input error, never a numerical failure of the estimator.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/common/config_bindings.h"
#include "core/common/enum_names.h"
#include "core/imu/noise_profile.h"
#include "core/linalg/flat_qr.h"

namespace marglab {

// What a keyframe marginalization does with the keyframe's visual measurements (Hsiung et al.,
// IROS 2018, §IV-A; docs/sparsification.md). Mid-frame marginalization keeps only the IMU
// constraints in all three.
//   discard — OKVIS / VINS-Mono: the landmarks the keyframe hosts go with it (all their
//             observations), its observations of other landmarks are dropped; the prior stays over
//             frame states only.
//   dense   — the keyframe and the landmarks only it observes go; every landmark it shares with
//             the window stays as a variable (a world point) and the prior over the Markov blanket
//             — states and landmarks — stays dense.
//   nfr     — the dense prior, sparsified by nonlinear factor recovery (eq. 16): unary pose,
//             velocity and bias factors and one pose–landmark factor per landmark replace it.
enum class MargStrategy { kDiscard, kDense, kNfr };
inline constexpr EnumNames<MargStrategy, 3> kMargStrategyNames{{{MargStrategy::kDiscard, "discard"},
                                                                {MargStrategy::kDense, "dense"},
                                                                {MargStrategy::kNfr, "nfr"}}};
inline const char* toString(MargStrategy value) { return nameOf(kMargStrategyNames, value); }
inline bool parseMargStrategy(const std::string& text, MargStrategy* value) {
  return parseName(kMargStrategyNames, text, value);
}

// The factors nfr recovers (docs/sparsification.md):
//   paper        — eqs. 11–12: a unary factor on every pose, velocity and bias of the blanket and a
//                  pose–landmark factor from the anchor pose to every landmark;
//   joint-states — the same pose–landmark factors, and one joint factor over all state blocks
//                  instead of the unary ones (information: the dense prior marginalized onto the
//                  states), so the correlations between the blanket's states are kept;
//   relative-pose — Mazuran et al.'s pose-graph topology: a unary factor on the anchor pose, a
//                  relative-pose factor between consecutive blanket poses, unary velocity and
//                  bias factors, and the same pose–landmark factors.
enum class SparsifyTopology { kPaper, kJointStates, kRelativePose };
inline constexpr EnumNames<SparsifyTopology, 3> kSparsifyTopologyNames{
    {{SparsifyTopology::kPaper, "paper"},
     {SparsifyTopology::kJointStates, "joint-states"},
     {SparsifyTopology::kRelativePose, "relative-pose"}}};
inline const char* toString(SparsifyTopology value) {
  return nameOf(kSparsifyTopologyNames, value);
}
inline bool parseSparsifyTopology(const std::string& text, SparsifyTopology* value) {
  return parseName(kSparsifyTopologyNames, text, value);
}

// When a frame's Levenberg–Marquardt stops (docs/design.md §3, Levenberg–Marquardt):
//   marglab — at most max_iterations linearizations, each with as many λ trials as it takes; stop
//             on a relative cost decrease < stop_relative_cost or max|δ| < stop_max_step;
//   basalt  — Basalt's rule (sqrt_keypoint_vio.cpp): at most max_iterations + 1 cost evaluations
//             in all (rejected λ trials count); stop on an absolute cost decrease < 1e-6
//             (kBasaltStopCost) or max|δ| < stop_max_step.
enum class LmStopRule { kMarglab, kBasalt };
inline constexpr EnumNames<LmStopRule, 2> kLmStopRuleNames{
    {{LmStopRule::kMarglab, "marglab"}, {LmStopRule::kBasalt, "basalt"}}};
inline const char* toString(LmStopRule value) { return nameOf(kLmStopRuleNames, value); }
inline bool parseLmStopRule(const std::string& text, LmStopRule* value) {
  return parseName(kLmStopRuleNames, text, value);
}
// When a landmark whose track ended is marginalized (marg_policy.h):
//   at-once    — after the frame in which its track ended: a marginalization event every frame
//                that loses a track (nearly every frame on KITTI);
//   with-state — Basalt's marginalize() (sqrt_keypoint_vo.cpp, vio_marg_lost_landmarks): it stays
//                in the window, its observations in the optimization, until the next event that
//                marginalizes a state (VO: a keyframe; VIO: nearly every frame), and goes with it.
// An f32 Hessian prior takes rounding at every event (README "Where we depart", item 6).
enum class LostLandmarkMarg { kAtOnce, kWithState };
inline constexpr EnumNames<LostLandmarkMarg, 2> kLostLandmarkMargNames{
    {{LostLandmarkMarg::kAtOnce, "at-once"}, {LostLandmarkMarg::kWithState, "with-state"}}};
inline const char* toString(LostLandmarkMarg value) {
  return nameOf(kLostLandmarkMargNames, value);
}

// What the LM step does with a damped reduced system whose LDLT has a pivot ≤ 0 (the system is not
// positive definite: in f32 a Hessian prior turned indefinite by rounding, README "Where we depart"):
//   fail  — a failed solve: retried with more damping, lm.max_failed_solves in a row end the run;
//   solve — Basalt's optimize() (sqrt_keypoint_vo.cpp): Eigen's pivoted LDLT factors a symmetric
//           indefinite matrix too, and its solution is taken as the step whatever the pivots'
//           signs; the cost test accepts or rejects it like any other step. Only a non-finite step
//           is a failed solve.
enum class IndefiniteSystem { kFail, kSolve };
inline constexpr EnumNames<IndefiniteSystem, 2> kIndefiniteSystemNames{
    {{IndefiniteSystem::kFail, "fail"}, {IndefiniteSystem::kSolve, "solve"}}};
inline const char* toString(IndefiniteSystem value) {
  return nameOf(kIndefiniteSystemNames, value);
}

// Basalt's absolute cost-decrease tolerance (its optimize() hard-codes 1e-6).
inline constexpr double kBasaltStopCost = 1e-6;

// Upper bound of lm.threads (and --threads): more threads than landmark chunks only thrash.
inline constexpr int kMaxLmThreads = 256;

struct EstimatorSettings {
  // window
  int max_kfs = 7;
  int max_states = 3;
  // residuals
  double obs_std_px = 0.5;
  double huber_px = 1.0;
  // gauge
  double gauge_prior_weight = 1e8;
  double gauge_prior_bias_gyro = 1e2;
  double gauge_prior_bias_accel = 1e1;
  // keyframes
  double kf_connected_ratio = 0.7;
  int min_frames_after_kf = -1;
  double min_baseline_m = 0.05;
  double marg_connected_share = 0.1;
  // lm
  int lm_max_iterations = 7;
  double lambda_init = 1e-4;
  double lambda_min = 1e-7;
  double lambda_max = 1e2;
  double stop_relative_cost = 1e-6;
  double stop_max_step = 1e-4;
  LmStopRule lm_stop_rule = LmStopRule::kMarglab;
  int max_failed_solves = 3;
  IndefiniteSystem lm_indefinite_system = IndefiniteSystem::kFail;
  // Damping of the landmark blocks too (H_ll += λ…). Off as in the paper's estimator (§5: "we skip
  // Jacobian scaling and landmark damping"), which lets the reduced system be formed once per
  // linearization.
  bool lm_landmark_damping = false;
  // Threads of the LM loop over landmark blocks (linearize, eliminate, reduce, back-substitute,
  // cost). 1 keeps timings comparable between variants and machines; the landmark-damped variant
  // of the loop stays serial.
  int lm_threads = 1;
  // marginalization
  RankThresholdMode qr_threshold_mode = RankThresholdMode::kAbsolute;
  double qr_threshold = -1;
  MargStrategy marg_strategy = MargStrategy::kDiscard;
  SparsifyTopology nfr_topology = SparsifyTopology::kPaper;
  bool nfr_rigid_deflation = false;
  bool psd_hessian_prior = false;
  LostLandmarkMarg lost_landmarks = LostLandmarkMarg::kAtOnce;
  // imu
  ImuNoiseProfile imu_noise_profile = ImuNoiseProfile::kKalibr;
  // estimator: the right camera's cx offset as a window variable (window.h), with a prior of
  // standard deviation right_cx_offset_prior_px around the loaded calibration.
  bool estimate_right_cx_offset = false;
  double right_cx_offset_prior_px = 1.0;

  // Every key with its range, bound to this struct's fields (the TOML layout above).
  Bindings bindings();
  // Written and read alone (window files, window_io.h): the sections of a run's whole config that
  // are not the estimator's are passed over when read. Throws InputError as applyToml does.
  std::string toToml() const;
  void loadTomlString(const std::string& text, const std::string& name);
};

// The violated relations between the estimator's keys (each key valid on its own); `origins`
// picks the key a message is about.
std::vector<ConfigProblem> estimatorRelationProblems(const EstimatorSettings& settings,
                                                     const std::vector<ConfigProblem>& range,
                                                     const ConfigOrigins& origins);

// What the estimator reports beside its estimate, decided by the run (core/pipeline/run_config.h):
// whether it keeps the shadow prior of the gauge diagnostics ([diagnostics] enabled), and the
// reprojection bound of its consistency count FrameResult::n_inconsistent ([failure]
// inconsistent_px, the tracking-failure rule).
struct EstimatorReporting {
  bool shadow_prior = true;
  double inconsistent_px = 5;
};

}  // namespace marglab
