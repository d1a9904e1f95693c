#include "core/estimator/estimator_settings.h"

#include <fmt/core.h>

#include <algorithm>

namespace marglab {

// The keys and their ranges (docs/design.md §9). The ranges follow what the estimator does with
// each value: e.g. max_kfs = 0 ended the run in "map::at", λ = 0 never grows (λ ← λν), a zero σ
// makes the cost non-finite, max_iterations = 0 skips the optimization, and the estimator silently
// raised max_states < 2 to 2. Upper bounds keep integers from overflowing and the window sane.
Bindings EstimatorSettings::bindings() {
  constexpr double kMaxWindow = 1000000;
  const char* m = "marginalization";
  return {
      numberKey("residuals", "obs_std_px", &obs_std_px, above(0)),
      integerKey("window", "max_kfs", &max_kfs, between(1, kMaxWindow)),
      integerKey("window", "max_states", &max_states, between(2, kMaxWindow)),
      numberKey("residuals", "huber_px", &huber_px, above(0)),
      numberKey("gauge", "prior_weight", &gauge_prior_weight, atLeast(0)),
      numberKey("gauge", "prior_bias_gyro", &gauge_prior_bias_gyro, atLeast(0)),
      numberKey("gauge", "prior_bias_accel", &gauge_prior_bias_accel, atLeast(0)),
      numberKey("keyframes", "connected_ratio", &kf_connected_ratio, Rule{0, 1, true}),
      integerKey("keyframes", "min_frames_after_kf", &min_frames_after_kf,
                 orSentinel(between(1, kMaxWindow), -1, "dataset default")),
      numberKey("keyframes", "min_baseline_m", &min_baseline_m, atLeast(0)),
      numberKey("keyframes", "marg_connected_share", &marg_connected_share, between(0, 1)),
      integerKey("lm", "max_iterations", &lm_max_iterations, between(1, 1000)),
      numberKey("lm", "lambda_init", &lambda_init, above(0)),
      numberKey("lm", "lambda_min", &lambda_min, above(0)),
      numberKey("lm", "lambda_max", &lambda_max, above(0)),
      numberKey("lm", "stop_relative_cost", &stop_relative_cost, atLeast(0)),
      numberKey("lm", "stop_max_step", &stop_max_step, atLeast(0)),
      choice("lm", "stop_rule", &lm_stop_rule, kLmStopRuleNames),
      integerKey("lm", "max_failed_solves", &max_failed_solves, between(1, 1000)),
      choice("lm", "indefinite_system", &lm_indefinite_system, kIndefiniteSystemNames),
      flagKey("lm", "landmark_damping", &lm_landmark_damping),
      integerKey("lm", "threads", &lm_threads, between(1, kMaxLmThreads)),
      choice(m, "qr_threshold_mode", &qr_threshold_mode, kRankThresholdModeNames),
      numberKey(m, "qr_threshold", &qr_threshold,
                orSentinel(atLeast(0), -1, "sqrt(eps) of the precision")),
      choice(m, "strategy", &marg_strategy, kMargStrategyNames),
      choice(m, "nfr_topology", &nfr_topology, kSparsifyTopologyNames),
      flagKey(m, "nfr_rigid_deflation", &nfr_rigid_deflation),
      flagKey(m, "psd_hessian_prior", &psd_hessian_prior),
      choice(m, "lost_landmarks", &lost_landmarks, kLostLandmarkMargNames),
      choice("imu", "noise_profile", &imu_noise_profile, kImuNoiseProfileNames),
      flagKey("estimator", "estimate_right_cx_offset", &estimate_right_cx_offset),
      // Above 0 (the prior keeps the offset determined before the camera moves); at most 100 px.
      numberKey("estimator", "right_cx_offset_prior_px", &right_cx_offset_prior_px,
                Rule{0, 100, true}),
  };
}

std::string EstimatorSettings::toToml() const {
  EstimatorSettings copy = *this;
  return bindingsToToml(copy.bindings());
}

void EstimatorSettings::loadTomlString(const std::string& text, const std::string& name) {
  ConfigOrigins origins;
  applyToml(bindings(), text, name, TomlScope{"", true}, &origins);
}

namespace {

bool valid(const std::vector<ConfigProblem>& range, const char* key) {
  return std::none_of(range.begin(), range.end(),
                      [key](const ConfigProblem& p) { return p.key == key; });
}

}  // namespace

std::vector<ConfigProblem> estimatorRelationProblems(const EstimatorSettings& s,
                                                     const std::vector<ConfigProblem>& range,
                                                     const ConfigOrigins& origins) {
  std::vector<ConfigProblem> out;
  if (valid(range, "lm.lambda_min") && valid(range, "lm.lambda_init") &&
      valid(range, "lm.lambda_max") &&
      !(s.lambda_min <= s.lambda_init && s.lambda_init <= s.lambda_max)) {
    const std::vector<std::string> keys = {"lm.lambda_min", "lm.lambda_init", "lm.lambda_max"};
    out.push_back(
        {relationKey(origins, s.lambda_min > s.lambda_max ? "lm.lambda_min" : "lm.lambda_init",
                     keys),
         fmt::format("lm.lambda_min = {}, lm.lambda_init = {}, lm.lambda_max = {}: "
                     "expected lambda_min <= lambda_init <= lambda_max",
                     s.lambda_min, s.lambda_init, s.lambda_max),
         keys});
  }
  if (valid(range, "marginalization.qr_threshold") &&
      s.qr_threshold_mode == RankThresholdMode::kRelative && s.qr_threshold >= 1) {
    const std::vector<std::string> keys = {"marginalization.qr_threshold",
                                           "marginalization.qr_threshold_mode"};
    out.push_back({relationKey(origins, "marginalization.qr_threshold", keys),
                   fmt::format("marginalization.qr_threshold = {} with qr_threshold_mode = "
                               "\"relative\": expected a relative threshold in [0, 1) (a column "
                               "counts as dependent when its remaining norm is at most the "
                               "threshold times its norm, so 1 or more drops every column)",
                               s.qr_threshold),
                   keys});
  }
  if (s.nfr_rigid_deflation &&
      (s.marg_strategy != MargStrategy::kNfr || s.nfr_topology != SparsifyTopology::kPaper)) {
    const std::vector<std::string> keys = {"marginalization.nfr_rigid_deflation",
                                           "marginalization.strategy",
                                           "marginalization.nfr_topology"};
    out.push_back({relationKey(origins, "marginalization.nfr_rigid_deflation", keys),
                   fmt::format("marginalization.nfr_rigid_deflation = true with strategy = \"{}\" "
                               "and nfr_topology = \"{}\": expected strategy \"nfr\" with "
                               "nfr_topology \"paper\" (the deflation acts on unary factors on "
                               "every pose of the blanket)",
                               toString(s.marg_strategy), toString(s.nfr_topology)),
                   keys});
  }
  if (s.estimate_right_cx_offset && s.marg_strategy != MargStrategy::kDiscard) {
    const std::vector<std::string> keys = {"estimator.estimate_right_cx_offset",
                                           "marginalization.strategy"};
    out.push_back({relationKey(origins, "estimator.estimate_right_cx_offset", keys),
                   fmt::format("estimator.estimate_right_cx_offset = true with strategy = \"{}\": "
                               "expected strategy \"discard\" (the stereo offset is not a "
                               "variable of the dense or nfr priors' factors)",
                               toString(s.marg_strategy)),
                   keys});
  }
  return out;
}

}  // namespace marglab
