#pragma once
// The full effective config of a run: the estimator's settings (core/estimator/estimator_settings.h)
// and the pipeline's own sections around it — the front-end, the failure rule, the simulation
// profile, the diagnostics — read from and written to TOML as one table of keys. Precedence:
// defaults < config file < --set < the option aliases (tools/run_args.h). The whole config is
// written into every results file (attribute config_toml), so a run can be repeated from its file.
//
// TOML layout of the pipeline's sections (all keys optional; unknown keys are errors), beside the
// estimator's [window] [residuals] [gauge] [keyframes] [lm] [marginalization] [imu]:
//   [frontend]      the image front-end's settings (core/frontend/frontend_options.h): grid_cell_px,
//                   pyramid_levels (−1: dataset default), max_iterations, window_px, fb_max_px,
//                   epipolar_max, ncc_min, ransac_px, min_eigen, corner_block_px, border_px,
//                   detect_margin_px (−1: dataset default), disparity_guesses_px (a list; []:
//                   dataset default), prediction ("estimator"|"tracker"|"none")
//   [calibration]   right_cx_shift_px: a correction of the dataset's stereo calibration
//                   (applyCalibration below; measured by `marglab datasets stereo-bias`)
//   [failure]       max_position_error_m (−1: dataset default), min_tracked_observations,
//                   max_tracking_loss_frames, inconsistent_px, max_inconsistent_share (the
//                   tracking-failure rule, core/pipeline/tracking_monitor.h)
//   [sim]           profile ("ideal"|"realistic"|"realistic-motion": simulated tracks' noise model,
//                   core/sim/sim_profile.h), imu_sample_time ("start"|"midpoint": when each
//                   synthetic IMU sample is taken, core/sim/imu_synth.h)
//   [diagnostics]   enabled, store_prior_every (0: never; k: every k-th event, default 25), seed
//
// Validation (docs/design.md §9): loading checks each value against its key's range; problems()
// checks the whole effective config, ranges and relations, after the command line has been
// applied. Messages name the key, the value, the allowed range and where the value came from.

#include <cstdint>
#include <string>
#include <vector>

#include "core/common/config_bindings.h"
#include "core/common/error.h"
#include "core/estimator/estimator_settings.h"
#include "core/frontend/frontend_options.h"
#include "core/sim/imu_synth.h"
#include "core/sim/sim_profile.h"

namespace marglab {

// When a run has failed (core/pipeline/tracking_monitor.h): its position error bound, and the
// tracking-failure rule — max_tracking_loss_frames frames in a row in which fewer than
// min_tracked_observations of the frame's observations continue landmarks of the window, or in
// which more than max_inconsistent_share of the observations checked after the optimization
// (FrameResult::n_checked) lie farther than inconsistent_px from their landmark's projection.
// max_inconsistent_share = 1 turns the second cause off. And the motion-consistency check
// (core/pipeline/motion_check.h): an estimate farther than max_motion_jump times the platform's
// recent motion per frame (at least motion_floor_m) from the constant-velocity prediction; 0 turns
// it off.
struct FailureSettings {
  double max_position_error_m = -1;
  int min_tracked_observations = 10;
  int max_tracking_loss_frames = 3;
  double inconsistent_px = 5;
  double max_inconsistent_share = 0.3;
  double max_motion_jump = 3;
  double motion_floor_m = 0.05;
};

// The gauge diagnostics of each marginalization event (core/diagnostics): on or off, how often the
// prior is stored whole, and the seed of their random directions.
struct DiagnosticsSettings {
  bool enabled = true;
  int store_prior_every = 25;
  std::uint64_t seed = 7;
  // Per marginalization, the rounding each stage injects against the same marginalization in
  // double (core/estimator/marg_rounding.h), written to <results>.rounding.csv; VO, sc
  // marginalization, sq storage only. Off: the run is unchanged.
  bool marg_rounding = false;
};

// A correction of the dataset's stereo calibration, applied where the calibration is loaded
// (applyCalibration), so that everything that reads it — the image front-end, the simulator, the
// estimator's rig — sees the corrected camera, as if the dataset's calibration file said so:
//   right_cx_shift_px  added to the principal point cx of the right camera (cam1). On a rectified
//                      pair (KITTI) every disparity u0 − u1 is read as f b / z + (cx0 − cx1), so
//                      the shift adds to every disparity the estimator explains: the correction
//                      of an additive disparity offset δ is −δ (core/frontend/stereo_bias.h
//                      measures δ against motion stereo). 0: the calibration as shipped.
// It is a config key (not a flag of the dataset) so that the results file records the correction
// a run used (config_toml).
inline constexpr double kMaxRightCxShiftPx = 50;  // the key's range: [−50, 50] px

struct CalibrationSettings {
  double right_cx_shift_px = 0;
};

// The calibration as the run uses it: `calib` with `settings` applied.
void applyCalibration(const CalibrationSettings& settings, StereoCalib* calib);

struct RunConfig {
  EstimatorSettings estimator;
  FrontendOptions frontend;
  CalibrationSettings calibration;
  FailureSettings failure;
  SimProfile sim_profile = SimProfile::kIdeal;
  ImuSampleTime sim_imu_sample_time = ImuSampleTime::kStart;
  SimOverrides sim_overrides;  // [sim] grid_cell_px, loss_probability, … (sim_profile.h)
  DiagnosticsSettings diagnostics;

  // Where each key ("section.key") was last set by loadToml, set or setOrigin; absent: the
  // default. Not part of the TOML; used for messages only.
  ConfigOrigins origins;

  // Overrides the fields present in a TOML file; throws InputError(file, line, what) on syntax
  // errors, unknown keys, wrong types and values outside their key's range.
  void loadToml(const std::string& path);
  // The same from a string (name used in messages); a table named foreign_section is skipped
  // (the [run] table of a spec file, core/pipeline/run_spec.h).
  void loadTomlString(const std::string& text, const std::string& name,
                      const std::string& foreign_section = "");
  // One key from the command line, "section.key=value" (applyAssignment).
  void set(const std::string& assignment, const std::string& option = "--set");
  std::string toToml() const;
  // The keys that decide the tracks of images (`datasets track`: [frontend] and [calibration]),
  // as TOML: two configs track alike when these are equal.
  std::string trackingToml() const;

  // Records that `key` ("lm.threads") was set by a command-line option.
  void setOrigin(const std::string& key, const std::string& option);
  // Every invalid value (range, finiteness) and violated relation of the whole config; empty when
  // it is valid.
  std::vector<ConfigProblem> problems() const;
  // The same, each located (locateProblem).
  std::vector<Problem> locatedProblems() const;
  // One problem so located; also for relations checked outside the config (runProblems).
  Problem located(const ConfigProblem& problem) const;
  // throwProblems(locatedProblems()) unless it is empty: every problem in one error.
  void validate() const;

  // What the estimator reports beside its estimate, as this config decides it.
  EstimatorReporting reporting() const {
    return EstimatorReporting{diagnostics.enabled, failure.inconsistent_px};
  }

  // A command-line value for `key` (a number or a name) checked against the key's range or names
  // (checkBindingText), for CLI11 validators: `marglab run` and sweep validation reject a bad
  // option value while parsing.
  static std::string checkValueText(const std::string& key, const std::string& text);

 private:
  // The one table of keys: the estimator's, then the pipeline's sections.
  Bindings bindings();
};

}  // namespace marglab
