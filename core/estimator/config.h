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
//                   stop_max_step, max_failed_solves, landmark_damping, threads
//   [marginalization] qr_threshold_mode ("absolute"|"relative"), qr_threshold (−1: √ε of the
//                   scalar type), strategy ("discard"|"dense"|"nfr", keyframe marginalization of
//                   VIO; see MargStrategy), nfr_topology ("paper"|"joint-states", see
//                   SparsifyTopology)
//   [failure]       max_position_error_m (−1: dataset default)
//   [diagnostics]   enabled, store_prior_every (0: never; k: every k-th event, default 25), seed

#include <cstdint>
#include <string>

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
const char* toString(MargStrategy strategy);
// False for an unknown name.
bool parseMargStrategy(const std::string& text, MargStrategy* strategy);

// The factors nfr recovers (docs/sparsification.md):
//   paper        — eqs. 11–12: a unary factor on every pose, velocity and bias of the blanket and a
//                  pose–landmark factor from the anchor pose to every landmark;
//   joint-states — the same pose–landmark factors, and one joint factor over all state blocks
//                  instead of the unary ones (information: the dense prior marginalized onto the
//                  states), so the correlations between the blanket's states are kept.
enum class SparsifyTopology { kPaper, kJointStates };
const char* toString(SparsifyTopology topology);
bool parseSparsifyTopology(const std::string& text, SparsifyTopology* topology);

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
  // failure
  double max_position_error_m = -1;
  // diagnostics
  bool diagnostics = true;
  int store_prior_every = 25;
  std::uint64_t diagnostics_seed = 7;

  // Overrides the fields present in a TOML file; throws InputError(file, line, what) on syntax
  // errors, unknown keys and wrong types.
  void loadToml(const std::string& path);
  // The same from a string (name used in messages).
  void loadTomlString(const std::string& text, const std::string& name);
  std::string toToml() const;
};

}  // namespace marglab
