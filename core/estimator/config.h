#pragma once
// Every number of the estimator (docs/design.md §3), in one struct, readable from and writable to
// TOML. Precedence: defaults < config file < command line. The full effective config is written
// into every results file (attribute config_toml), so a run can be repeated from its file.
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
//                   max_failed_solves, landmark_damping, threads
//   [marginalization] qr_threshold_mode ("absolute"|"relative"), qr_threshold (−1: √ε of the
//                   scalar type), strategy ("discard"|"dense"|"nfr", keyframe marginalization of
//                   VIO; see MargStrategy), nfr_topology ("paper"|"joint-states"|"relative-pose",
//                   see SparsifyTopology), nfr_rigid_deflation (true: nfr's unary factors lose
//                   their information in excess of the dense prior's along the window's rigid
//                   motions, core/sparsify/rigid_deflation.h; needs strategy "nfr" and
//                   nfr_topology "paper"), psd_hessian_prior (true: a Hessian prior — storages
//                   sq, sqp, sqj — is stored as the Hessian JᵀJ, Jᵀr of its clamped LDLT square
//                   root, positive semidefinite like a square-root prior; README item 5)
//   [frontend]      the image front-end's settings (core/frontend/frontend_options.h): grid_cell_px,
//                   pyramid_levels (−1: dataset default), max_iterations, window_px, fb_max_px,
//                   epipolar_max, ncc_min, ransac_px, min_eigen, corner_block_px, border_px,
//                   detect_margin_px (−1: dataset default), disparity_guesses_px (a list; []: dataset default), prediction
//                   ("estimator"|"tracker"|"none")
//   [failure]       max_position_error_m (−1: dataset default), min_tracked_observations,
//                   max_tracking_loss_frames, inconsistent_px, max_inconsistent_share (the
//                   tracking-failure rule, core/pipeline/tracking_monitor.h)
//   [imu]           noise_profile ("kalibr"|"basalt": the IMU densities of VIO runs, for the
//                   synthetic IMU and the estimator's weights; see core/imu/noise_profile.h)
//   [sim]           profile ("ideal"|"realistic": simulated tracks' noise model,
//   core/sim/sim_profile.h) [diagnostics]   enabled, store_prior_every (0: never; k: every k-th
//   event, default 25), seed
//
// Validation (docs/design.md §9): every key has a range; a value outside it, a non-finite number
// or a violated relation between keys (lambda_min ≤ lambda_init ≤ lambda_max; a relative
// qr_threshold below 1; nfr_rigid_deflation only with strategy nfr, topology paper) is an
// input error, never a numerical failure of the estimator. loadToml checks each value it reads
// against its key's range (integers before they are narrowed, so 1e12 is an error and never
// wraps); validate() checks the whole effective config after the command line has been applied.
// Messages name the key, the value, the allowed range and where the value came from (FILE:LINE of
// a TOML file, or the command-line option).

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/common/enum_names.h"
#include "core/common/error.h"
#include "core/frontend/frontend_options.h"
#include "core/imu/noise_profile.h"
#include "core/linalg/flat_qr.h"
#include "core/sim/sim_profile.h"

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
inline constexpr EnumNames<MargStrategy, 3> kMargStrategyNames{{{MargStrategy::kDiscard, "discard"}, {MargStrategy::kDense, "dense"}, {MargStrategy::kNfr, "nfr"}}};
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
inline constexpr EnumNames<SparsifyTopology, 3> kSparsifyTopologyNames{{{SparsifyTopology::kPaper, "paper"}, {SparsifyTopology::kJointStates, "joint-states"}, {SparsifyTopology::kRelativePose, "relative-pose"}}};
inline const char* toString(SparsifyTopology value) { return nameOf(kSparsifyTopologyNames, value); }
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
inline constexpr EnumNames<LmStopRule, 2> kLmStopRuleNames{{{LmStopRule::kMarglab, "marglab"}, {LmStopRule::kBasalt, "basalt"}}};
inline const char* toString(LmStopRule value) { return nameOf(kLmStopRuleNames, value); }
inline bool parseLmStopRule(const std::string& text, LmStopRule* value) {
  return parseName(kLmStopRuleNames, text, value);
}
// Basalt's absolute cost-decrease tolerance (its optimize() hard-codes 1e-6).
inline constexpr double kBasaltStopCost = 1e-6;

// Upper bound of lm.threads (and --threads): more threads than landmark chunks only thrash.
inline constexpr int kMaxLmThreads = 256;

// Where a config value came from: a TOML file and line, or a command-line option ("--threads").
struct ConfigOrigin {
  std::string file;
  int line = 0;
  std::string option;
  std::string describe() const;  // "cfg.toml:3", "--threads", "" (default)
};

// One invalid value or relation of a config; `message` names the key(s), value(s) and the allowed
// range, without the location (see EstimatorConfig::origins).
struct ConfigProblem {
  std::string key;  // "lm.max_iterations"; for a relation, the key the message is about
  std::string message;
  // A relation's keys, whose origins validate() names.
  std::vector<std::string> related = {};
};

struct EstimatorConfig {
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
  // frontend
  FrontendOptions frontend;
  // failure
  double max_position_error_m = -1;
  // A run has lost the scene after max_tracking_loss_frames frames in a row in which fewer than
  // min_tracked_observations of the frame's observations continue landmarks of the window, or in
  // which more than max_inconsistent_share of the observations checked after the optimization
  // (FrameResult::n_checked) lie farther than inconsistent_px from their landmark's projection
  // (core/pipeline/tracking_monitor.h). max_inconsistent_share = 1 turns the second cause off.
  int min_tracked_observations = 10;
  int max_tracking_loss_frames = 3;
  double inconsistent_px = 5;
  double max_inconsistent_share = 0.3;
  // imu
  ImuNoiseProfile imu_noise_profile = ImuNoiseProfile::kKalibr;
  // sim
  SimProfile sim_profile = SimProfile::kIdeal;
  // diagnostics
  bool diagnostics = true;
  int store_prior_every = 25;
  std::uint64_t diagnostics_seed = 7;

  // Where each key ("section.key") was last set by loadToml or setOrigin; absent: the default.
  // Not part of the TOML; used for messages only.
  std::map<std::string, ConfigOrigin> origins;

  // Overrides the fields present in a TOML file; throws InputError(file, line, what) on syntax
  // errors, unknown keys, wrong types and values outside their key's range.
  void loadToml(const std::string& path);
  // The same from a string (name used in messages); a table named foreign_section is skipped
  // (the [run] table of a spec file, core/pipeline/run_spec.h).
  void loadTomlString(const std::string& text, const std::string& name,
                      const std::string& foreign_section = "");
  // One key from the command line, "section.key=value" (`--set`, a sweep group's `set`): parsed
  // and range-checked as its TOML line would be (a name may omit the quotes); its origin becomes
  // `option`. Throws UsageError naming the option, the key and what was expected.
  void set(const std::string& assignment, const std::string& option = "--set");
  std::string toToml() const;

  // Records that `key` ("lm.threads") was set by a command-line option.
  void setOrigin(const std::string& key, const std::string& option);
  // Every invalid value (range, finiteness) and violated relation of the whole config; empty when
  // it is valid.
  std::vector<ConfigProblem> problems() const;
  // The same, each with where its value came from: the command-line option (a usage error naming
  // it), else the TOML file and line (file "config", line 0, for a default or a value set in code);
  // a relation's message names every key involved with its origin.
  std::vector<Problem> locatedProblems() const;
  // One problem so located; also for relations checked outside the config (runProblems).
  Problem located(const ConfigProblem& problem) const;
  // throwProblems(locatedProblems()) unless it is empty: every problem in one error.
  void validate() const;

  // A command-line value for `key` (a number or a name) checked against the key's range or names;
  // "" when it is accepted, else
  // the reason ("lm.threads = 0: expected an integer in [1, 256]"). Throws std::logic_error for
  // an unknown key. For CLI11 validators, so that `marglab run` and sweep validation reject a bad
  // option value while parsing.
  static std::string checkValueText(const std::string& key, const std::string& text);
};

}  // namespace marglab
