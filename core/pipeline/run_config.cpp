#include "core/pipeline/run_config.h"

#include <limits>

#include "core/io/text_input.h"

namespace marglab {
namespace {

// The [frontend] keys (core/frontend/frontend_options.h). The ranges keep OpenCV's LK and
// corner detector inside what they accept (a window of at least 5 px, a block of at least 2) and
// the checks meaningful (an NCC bound in [−1, 1], a sine bound in (0, 1]).
void addFrontendBindings(FrontendOptions& f, Bindings* list) {
  const char* s = "frontend";
  const Rule dataset_default = orSentinel(between(0, 10000), -1, "dataset default");
  list->push_back(integerKey(s, "grid_cell_px", &f.grid_cell_px,
                             orSentinel(between(8, 10000), -1, "dataset default")));
  list->push_back(integerKey(s, "pyramid_levels", &f.pyramid_levels,
                             orSentinel(between(1, 8), -1, "dataset default")));
  list->push_back(integerKey(s, "max_iterations", &f.max_iterations, between(1, 100)));
  list->push_back(integerKey(s, "window_px", &f.window_px, between(5, 101)));
  list->push_back(numberKey(s, "fb_max_px", &f.fb_max_px, above(0)));
  list->push_back(numberKey(s, "epipolar_max", &f.epipolar_max, Rule{0, 1, true}));
  list->push_back(numberKey(s, "ncc_min", &f.ncc_min, between(-1, 1)));
  list->push_back(numberKey(s, "ransac_px", &f.ransac_px, above(0)));
  list->push_back(numberKey(s, "min_eigen", &f.min_eigen, atLeast(0)));
  list->push_back(integerKey(s, "corner_block_px", &f.corner_block_px, between(2, 31)));
  list->push_back(integerKey(s, "border_px", &f.border_px, between(0, 10000)));
  list->push_back(integerKey(s, "detect_margin_px", &f.detect_margin_px, dataset_default));
  Binding guesses{s, "disparity_guesses_px"};
  guesses.list = &f.disparity_guesses_px;
  guesses.rule = between(0, 10000);
  list->push_back(guesses);
  list->push_back(choice(s, "prediction", &f.prediction, kMotionPredictionSourceNames));
}

// A shift of tens of pixels is no longer a calibration error but a different camera.
void addCalibrationBindings(CalibrationSettings& c, Bindings* list) {
  list->push_back(numberKey("calibration", "right_cx_shift_px", &c.right_cx_shift_px,
                            between(-kMaxRightCxShiftPx, kMaxRightCxShiftPx)));
}

void addFailureBindings(FailureSettings& f, Bindings* list) {
  const char* s = "failure";
  list->push_back(numberKey(s, "max_position_error_m", &f.max_position_error_m,
                            orSentinel(above(0), -1, "dataset default")));
  list->push_back(
      integerKey(s, "min_tracked_observations", &f.min_tracked_observations, between(0, 100000)));
  list->push_back(
      integerKey(s, "max_tracking_loss_frames", &f.max_tracking_loss_frames, between(1, 1000000)));
  list->push_back(numberKey(s, "inconsistent_px", &f.inconsistent_px, above(0)));
  list->push_back(numberKey(s, "max_inconsistent_share", &f.max_inconsistent_share, between(0, 1)));
  list->push_back(
      numberKey(s, "max_motion_jump", &f.max_motion_jump, orSentinel(above(0), 0, "off")));
  list->push_back(numberKey(s, "motion_floor_m", &f.motion_floor_m, above(0)));
}

// [sim]: the measurement profile and single settings replaced on top of it (sim_profile.h).
void addSimBindings(SimProfile& profile, ImuSampleTime& imu_sample_time, SimOverrides& o,
                    Bindings* list) {
  const char* s = "sim";
  list->push_back(choice(s, "profile", &profile, kSimProfileNames));
  list->push_back(choice(s, "imu_sample_time", &imu_sample_time, kImuSampleTimeNames));
  list->push_back(numberKey(s, "grid_cell_px", &o.grid_cell_px,
                            orSentinel(between(8, 10000), -1, "the dataset default")));
  const Rule probability = orSentinel(between(0, 1), -1, "the profile's");
  list->push_back(numberKey(s, "loss_probability", &o.loss_probability, probability));
  list->push_back(
      numberKey(s, "stereo_failure_probability", &o.stereo_failure_probability, probability));
  list->push_back(numberKey(s, "facade_offset_scale", &o.facade_offset_scale,
                            orSentinel(between(0.1, 10), -1, "the dataset's world")));
}

void addDiagnosticsBindings(DiagnosticsSettings& d, Bindings* list) {
  list->push_back(flagKey("diagnostics", "enabled", &d.enabled));
  list->push_back(integerKey("diagnostics", "store_prior_every", &d.store_prior_every,
                             between(0, std::numeric_limits<int>::max())));
  Binding seed{"diagnostics", "seed", nullptr, nullptr, nullptr, &d.seed};
  seed.rule = atLeast(0);  // and a TOML integer, i.e. at most 2^63 − 1
  list->push_back(seed);
  list->push_back(flagKey("diagnostics", "marg_rounding", &d.marg_rounding));
}

}  // namespace

void applyCalibration(const CalibrationSettings& settings, StereoCalib* calib) {
  calib->cam1.cx += settings.right_cx_shift_px;
}

Bindings RunConfig::bindings() {
  Bindings list = estimator.bindings();
  addFrontendBindings(frontend, &list);
  addCalibrationBindings(calibration, &list);
  addFailureBindings(failure, &list);
  addSimBindings(sim_profile, sim_imu_sample_time, sim_overrides, &list);
  addDiagnosticsBindings(diagnostics, &list);
  return list;
}

void RunConfig::loadTomlString(const std::string& text, const std::string& name,
                               const std::string& foreign_section) {
  applyToml(bindings(), text, name, TomlScope{foreign_section, false}, &origins);
}

void RunConfig::set(const std::string& assignment, const std::string& option) {
  applyAssignment(bindings(), assignment, option, &origins);
}

void RunConfig::loadToml(const std::string& path) {
  loadTomlString(readTextInput(path, "the config file", kSettingsTextLimits), path);
}

std::string RunConfig::toToml() const {
  RunConfig copy = *this;
  return bindingsToToml(copy.bindings());
}

std::string RunConfig::trackingToml() const {
  RunConfig copy = *this;
  Bindings list;
  addFrontendBindings(copy.frontend, &list);
  addCalibrationBindings(copy.calibration, &list);
  return bindingsToToml(list);
}

void RunConfig::setOrigin(const std::string& key, const std::string& option) {
  origins[key] = ConfigOrigin{"", 0, option};
}

std::vector<ConfigProblem> RunConfig::problems() const {
  RunConfig copy = *this;
  std::vector<ConfigProblem> out = rangeProblems(copy.bindings());
  const std::vector<ConfigProblem> relations = estimatorRelationProblems(estimator, out, origins);
  out.insert(out.end(), relations.begin(), relations.end());
  return out;
}

Problem RunConfig::located(const ConfigProblem& problem) const {
  return locateProblem(problem, origins);
}

std::vector<Problem> RunConfig::locatedProblems() const {
  std::vector<Problem> out;
  for (const ConfigProblem& p : problems()) out.push_back(located(p));
  return out;
}

void RunConfig::validate() const {
  const std::vector<Problem> list = locatedProblems();
  if (!list.empty()) throwProblems(list);
}

std::string RunConfig::checkValueText(const std::string& key, const std::string& text) {
  RunConfig probe;
  return checkBindingText(probe.bindings(), key, text);
}

}  // namespace marglab
