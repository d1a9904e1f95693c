// RunConfig validation (docs/design.md §9, issue #18 items 5, 6, 11): every value outside
// its key's range, every non-finite number and every violated relation between keys is an input
// error naming the key, the value, the allowed range and where the value came from — never a
// wrapped integer, never a run that "succeeds" without optimizing or fails numerically.

#include <gtest/gtest.h>

#include <sstream>
#include <string>

#include "core/common/error.h"
#include "core/pipeline/run_config.h"

namespace marglab {
namespace {

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(ConfigValidation, DefaultsAndTheirRoundTripAreValid) {
  RunConfig config;
  EXPECT_TRUE(config.problems().empty());
  EXPECT_NO_THROW(config.validate());
  RunConfig round_trip;
  EXPECT_NO_THROW(round_trip.loadTomlString(config.toToml(), "defaults.toml"));
  EXPECT_NO_THROW(round_trip.validate());
}

struct BadValue {
  const char* name;
  const char* toml;     // line 1 is the section, line 2 the key
  const char* message;  // part of the message: key, value and range
};

class BadConfigValue : public ::testing::TestWithParam<BadValue> {};

TEST_P(BadConfigValue, IsAnInputErrorNamingFileLineKeyValueAndRange) {
  const BadValue& bad = GetParam();
  RunConfig config;
  try {
    config.loadTomlString(bad.toml, "cfg.toml");
    FAIL() << "accepted:\n" << bad.toml;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "cfg.toml");
    EXPECT_EQ(e.line(), 2) << e.what();
    EXPECT_TRUE(contains(e.what(), bad.message)) << e.what() << "\nexpected: " << bad.message;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Issue18, BadConfigValue,
    ::testing::Values(
        // Item 5: integers are range-checked before they are narrowed (1e12 used to wrap to
        // −727379968), and 0 iterations used to give status ok without any optimization.
        BadValue{"MaxIterations1e12", "[lm]\nmax_iterations = 1e12\n",
                 "lm.max_iterations = 1000000000000: expected an integer in [1, 1000]"},
        BadValue{"MaxIterationsAboveInt", "[lm]\nmax_iterations = 3000000000\n",
                 "lm.max_iterations = 3000000000: expected an integer in [1, 1000]"},
        BadValue{"MaxIterationsHuge", "[lm]\nmax_iterations = 1e300\n",
                 "lm.max_iterations = 1e+300: expected an integer in [1, 1000]"},
        BadValue{"MaxIterationsZero", "[lm]\nmax_iterations = 0\n",
                 "lm.max_iterations = 0: expected an integer in [1, 1000]"},
        BadValue{"MaxIterationsFraction", "[lm]\nmax_iterations = 7.5\n",
                 "expected an integer in [1, 1000] for lm.max_iterations"},
        BadValue{"HuberZero", "[residuals]\nhuber_px = 0\n",
                 "residuals.huber_px = 0: expected a finite number > 0"},
        BadValue{"HuberNegative", "[residuals]\nhuber_px = -1\n",
                 "residuals.huber_px = -1: expected a finite number > 0"},
        BadValue{"ObsStdInf", "[residuals]\nobs_std_px = inf\n",
                 "residuals.obs_std_px = inf: expected a finite number > 0"},
        BadValue{"ObsStdZero", "[residuals]\nobs_std_px = 0\n",
                 "residuals.obs_std_px = 0: expected a finite number > 0"},
        BadValue{"ObsStdNan", "[residuals]\nobs_std_px = nan\n",
                 "residuals.obs_std_px = nan: expected a finite number > 0"},
        BadValue{"NegativeGaugeWeight", "[gauge]\nprior_weight = -1e8\n",
                 "gauge.prior_weight = -100000000: expected a finite number >= 0"},
        BadValue{"NegativeBiasWeight", "[gauge]\nprior_bias_accel = -1\n",
                 "gauge.prior_bias_accel = -1: expected a finite number >= 0"},
        BadValue{"ConnectedRatioFive", "[keyframes]\nconnected_ratio = 5\n",
                 "keyframes.connected_ratio = 5: expected a finite number in (0, 1]"},
        BadValue{"ConnectedRatioZero", "[keyframes]\nconnected_ratio = 0\n",
                 "keyframes.connected_ratio = 0: expected a finite number in (0, 1]"},
        BadValue{"MargShareAboveOne", "[keyframes]\nmarg_connected_share = 1.5\n",
                 "keyframes.marg_connected_share = 1.5: expected a finite number in [0, 1]"},
        BadValue{"MinFramesAfterKfZero", "[keyframes]\nmin_frames_after_kf = 0\n",
                 "keyframes.min_frames_after_kf = 0: expected -1 (dataset default) or an integer "
                 "in [1, 1000000]"},
        BadValue{"NegativeBaseline", "[keyframes]\nmin_baseline_m = -0.1\n",
                 "keyframes.min_baseline_m = -0.1: expected a finite number >= 0"},
        // max_kfs = 0 used to end in "map::at"; max_states = 1 was silently raised to 2.
        BadValue{"MaxKfsZero", "[window]\nmax_kfs = 0\n",
                 "window.max_kfs = 0: expected an integer in [1, 1000000]"},
        BadValue{"MaxStatesOne", "[window]\nmax_states = 1\n",
                 "window.max_states = 1: expected an integer in [2, 1000000]"},
        BadValue{"LambdaZero", "[lm]\nlambda_init = 0\n",
                 "lm.lambda_init = 0: expected a finite number > 0"},
        BadValue{"LambdaMaxInf", "[lm]\nlambda_max = inf\n",
                 "lm.lambda_max = inf: expected a finite number > 0"},
        BadValue{"NegativeStop", "[lm]\nstop_relative_cost = -1e-6\n",
                 "lm.stop_relative_cost = -1e-06: expected a finite number >= 0"},
        BadValue{"FailedSolvesZero", "[lm]\nmax_failed_solves = 0\n",
                 "lm.max_failed_solves = 0: expected an integer in [1, 1000]"},
        // Item 6: 10000 threads thrashed the machine.
        BadValue{"Threads10000", "[lm]\nthreads = 10000\n",
                 "lm.threads = 10000: expected an integer in [1, 256]"},
        BadValue{"ThreadsZero", "[lm]\nthreads = 0\n",
                 "lm.threads = 0: expected an integer in [1, 256]"},
        // Item 11: NaN silently became the default threshold.
        BadValue{"QrThresholdNan", "[marginalization]\nqr_threshold = nan\n",
                 "marginalization.qr_threshold = nan: expected -1 (sqrt(eps) of the precision) or "
                 "a finite number >= 0"},
        BadValue{"QrThresholdMinusTwo", "[marginalization]\nqr_threshold = -2\n",
                 "marginalization.qr_threshold = -2: expected -1"},
        BadValue{"PositionBoundZero", "[failure]\nmax_position_error_m = 0\n",
                 "failure.max_position_error_m = 0: expected -1 (dataset default) or a finite "
                 "number > 0"},
        BadValue{"StorePriorEveryNegative", "[diagnostics]\nstore_prior_every = -5\n",
                 "diagnostics.store_prior_every = -5: expected an integer in [0, 2147483647]"},
        BadValue{"NegativeSeed", "[diagnostics]\nseed = -1\n",
                 "diagnostics.seed = -1: expected an integer >= 0"}),
    [](const auto& info) { return std::string(info.param.name); });

// The [frontend] keys (core/frontend/frontend_options.h) in the same range table.
INSTANTIATE_TEST_SUITE_P(
    Frontend, BadConfigValue,
    ::testing::Values(
        BadValue{"GridZero", "[frontend]\ngrid_cell_px = 0\n",
                 "frontend.grid_cell_px = 0: expected -1 (dataset default) or an integer in [8, "
                 "10000]"},
        BadValue{"LevelsNine", "[frontend]\npyramid_levels = 9\n",
                 "frontend.pyramid_levels = 9: expected -1 (dataset default) or an integer in [1, "
                 "8]"},
        BadValue{"MarginNegative", "[frontend]\ndetect_margin_px = -2\n",
                 "frontend.detect_margin_px = -2: expected -1 (dataset default) or an integer in "
                 "[0, 10000]"},
        BadValue{"WindowThree", "[frontend]\nwindow_px = 3\n",
                 "frontend.window_px = 3: expected an integer in [5, 101]"},
        BadValue{"FbNan", "[frontend]\nfb_max_px = nan\n",
                 "frontend.fb_max_px = nan: expected a finite number > 0"},
        BadValue{"NccAboveOne", "[frontend]\nncc_min = 1.5\n",
                 "frontend.ncc_min = 1.5: expected a finite number in [-1, 1]"},
        BadValue{"EpipolarZero", "[frontend]\nepipolar_max = 0\n",
                 "frontend.epipolar_max = 0: expected a finite number in (0, 1]"},
        BadValue{"RansacZero", "[frontend]\nransac_px = 0\n",
                 "frontend.ransac_px = 0: expected a finite number > 0"},
        BadValue{"GuessNegative", "[frontend]\ndisparity_guesses_px = [0, -5]\n",
                 "frontend.disparity_guesses_px[1]: expected a finite number in [0, 10000]"},
        BadValue{"GuessesNotAList", "[frontend]\ndisparity_guesses_px = 12\n",
                 "expected a list of numbers for frontend.disparity_guesses_px"},
        BadValue{"PredictionUnknown", "[frontend]\nprediction = \"imu\"\n",
                 "expected \"estimator\", \"tracker\" or \"none\" for frontend.prediction"},
        BadValue{"TrackingFramesZero", "[failure]\nmax_tracking_loss_frames = 0\n",
                 "failure.max_tracking_loss_frames = 0: expected an integer in [1, 1000000]"},
        BadValue{"TrackedObservationsNegative", "[failure]\nmin_tracked_observations = -1\n",
                 "failure.min_tracked_observations = -1: expected an integer in [0, 100000]"},
        BadValue{"InconsistentPxZero", "[failure]\ninconsistent_px = 0\n",
                 "failure.inconsistent_px = 0: expected a finite number > 0"},
        BadValue{"InconsistentShareAboveOne", "[failure]\nmax_inconsistent_share = 1.5\n",
                 "failure.max_inconsistent_share = 1.5: expected a finite number in [0, 1]"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(ConfigValidation, FrontendKeysRoundTripAndResolvePerDataset) {
  RunConfig config;
  config.loadTomlString(
      "[frontend]\nwindow_px = 21\ndisparity_guesses_px = [0, 20.5]\nprediction = \"tracker\"\n",
      "cfg.toml");
  RunConfig round_trip;
  round_trip.loadTomlString(config.toToml(), "again.toml");
  EXPECT_EQ(round_trip.frontend.window_px, 21);
  EXPECT_EQ(round_trip.frontend.disparity_guesses_px, (std::vector<double>{0, 20.5}));
  EXPECT_EQ(round_trip.frontend.prediction, MotionPredictionSource::kTracker);
  const FrontendOptions kitti = resolveFrontendOptions(FrontendOptions{}, DatasetKind::kKitti);
  const FrontendOptions euroc = resolveFrontendOptions(FrontendOptions{}, DatasetKind::kEuroc);
  EXPECT_EQ(kitti.grid_cell_px, 30);
  EXPECT_EQ(kitti.pyramid_levels, 4);
  EXPECT_EQ(euroc.grid_cell_px, 50);
  EXPECT_EQ(euroc.pyramid_levels, 3);
  EXPECT_EQ(kitti.detect_margin_px, 150);
  EXPECT_EQ(euroc.detect_margin_px, 0);
  EXPECT_FALSE(kitti.disparity_guesses_px.empty());
  // A configured value is kept, not replaced by the dataset's.
  FrontendOptions configured;
  configured.pyramid_levels = 2;
  EXPECT_EQ(resolveFrontendOptions(configured, DatasetKind::kKitti).pyramid_levels, 2);
}

TEST(ConfigValidation, CalibrationShiftRoundTripsAndIsRangeChecked) {
  RunConfig config;
  EXPECT_EQ(config.calibration.right_cx_shift_px, 0.0);  // the calibration as shipped
  config.loadTomlString("[calibration]\nright_cx_shift_px = -0.3832\n", "bias.toml");
  RunConfig round_trip;
  round_trip.loadTomlString(config.toToml(), "again.toml");
  EXPECT_EQ(round_trip.calibration.right_cx_shift_px, -0.3832);
  round_trip.set("calibration.right_cx_shift_px=50");
  EXPECT_EQ(round_trip.calibration.right_cx_shift_px, 50.0);
  for (const char* bad : {"50.5", "-51", "nan", "inf"}) {
    RunConfig c;
    try {
      c.loadTomlString(std::string("[calibration]\nright_cx_shift_px = ") + bad + "\n", "b.toml");
      ADD_FAILURE() << "accepted " << bad;
    } catch (const InputError& e) {
      EXPECT_EQ(e.line(), 2) << e.what();
      EXPECT_TRUE(contains(e.what(), "calibration.right_cx_shift_px")) << e.what();
      EXPECT_TRUE(contains(e.what(), "[-50, 50]")) << e.what();
    }
  }
}

TEST(ConfigValidation, ValuesAtTheEdgesOfTheirRangesAreAccepted) {
  RunConfig config;
  config.loadTomlString(
      "[window]\nmax_kfs = 1\nmax_states = 2\n"
      "[keyframes]\nconnected_ratio = 1\nmin_frames_after_kf = -1\nmarg_connected_share = 0\n"
      "[lm]\nmax_iterations = 1e3\nthreads = 256\nlambda_min = 1e-4\nlambda_init = 1e-4\n"
      "[marginalization]\nqr_threshold = 0\n"
      "[gauge]\nprior_weight = 0\n"
      "[diagnostics]\nstore_prior_every = 0\n",
      "edges.toml");
  EXPECT_EQ(config.estimator.lm_max_iterations, 1000);
  EXPECT_TRUE(config.problems().empty());
  EXPECT_NO_THROW(config.validate());
}

// Relations between keys are checked on the whole effective config, and the message names every
// key involved with the place it came from.
TEST(ConfigValidation, LambdaOrderIsARelationNamingTheFileLine) {
  RunConfig config;
  config.loadTomlString("[lm]\nmax_iterations = 5\nlambda_min = 10\nlambda_max = 1\n", "cfg.toml");
  ASSERT_EQ(config.problems().size(), 1u);
  try {
    config.validate();
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "cfg.toml");
    EXPECT_EQ(e.line(), 3) << e.what();
    EXPECT_TRUE(
        contains(e.what(), "lm.lambda_min = 10, lm.lambda_init = 0.0001, lm.lambda_max = 1"))
        << e.what();
    EXPECT_TRUE(contains(e.what(),
                         "(lm.lambda_min from cfg.toml:3, lm.lambda_init from the "
                         "default, lm.lambda_max from cfg.toml:4)"))
        << e.what();
    EXPECT_TRUE(contains(e.what(), "expected lambda_min <= lambda_init <= lambda_max")) << e.what();
  }
  RunConfig above_max;
  above_max.loadTomlString("[lm]\nlambda_init = 1e3\n", "init.toml");
  try {
    above_max.validate();
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 2) << e.what();
  }
}

// Every problem is reported, not only the first: two violated relations from one file, and a
// command-line value on top.
TEST(ConfigValidation, TwoProblemsAtOnceAreBothReported) {
  RunConfig config;
  config.loadTomlString(
      "[lm]\nlambda_min = 10\nlambda_max = 1\n[marginalization]\nnfr_rigid_deflation = true\n",
      "two.toml");
  ASSERT_EQ(config.locatedProblems().size(), 2u);
  try {
    config.validate();
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 2) << e.what();
    EXPECT_TRUE(contains(e.what(), "expected lambda_min <= lambda_init <= lambda_max")) << e.what();
    EXPECT_TRUE(contains(e.what(),
                         "\n  also: two.toml:5: marginalization.nfr_rigid_deflation = "
                         "true with strategy = \"discard\""))
        << e.what();
  }
  config.estimator.lm_threads = 0;
  config.setOrigin("lm.threads", "--threads");
  const std::vector<Problem> problems = config.locatedProblems();
  ASSERT_EQ(problems.size(), 3u);
  EXPECT_EQ(problems[0].kind, ProblemKind::kUsage);
  EXPECT_EQ(problems[0].message, "--threads: lm.threads = 0: expected an integer in [1, 256]");
}

TEST(ConfigValidation, RelativeQrThresholdMustBeBelowOne) {
  RunConfig config;
  config.loadTomlString("[marginalization]\nqr_threshold_mode = \"relative\"\nqr_threshold = 1\n",
                        "qr.toml");
  try {
    config.validate();
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 3) << e.what();
    EXPECT_TRUE(contains(e.what(), "expected a relative threshold in [0, 1)")) << e.what();
  }
  config.estimator.qr_threshold_mode =
      RankThresholdMode::kAbsolute;  // an absolute 1 is a valid threshold
  EXPECT_NO_THROW(config.validate());
}

// A value set from the command line is a usage error naming the option (exit code 2).
TEST(ConfigValidation, CommandLineValuesNameTheOption) {
  RunConfig config;
  config.estimator.lm_threads = 10000;
  config.setOrigin("lm.threads", "--threads");
  try {
    config.validate();
    FAIL();
  } catch (const UsageError& e) {
    EXPECT_EQ(std::string(e.what()),
              "--threads: lm.threads = 10000: expected an integer in [1, 256]");
  }
  // A value set in code (no origin) is still refused, as input.
  RunConfig in_code;
  in_code.estimator.obs_std_px = 0;
  EXPECT_THROW(in_code.validate(), InputError);
}

TEST(ConfigValidation, CheckValueTextForCommandLineOptions) {
  EXPECT_EQ(RunConfig::checkValueText("lm.threads", "4"), "");
  EXPECT_EQ(RunConfig::checkValueText("lm.threads", "0"),
            "lm.threads = 0: expected an integer in [1, 256]");
  EXPECT_EQ(RunConfig::checkValueText("lm.threads", "2.5"),
            "lm.threads = 2.5: expected an integer in [1, 256]");
  EXPECT_EQ(RunConfig::checkValueText("marginalization.qr_threshold", "nan"),
            "marginalization.qr_threshold = nan: expected -1 (sqrt(eps) of the precision) or a "
            "finite number >= 0");
  EXPECT_EQ(RunConfig::checkValueText("marginalization.qr_threshold", "-1"), "");
  EXPECT_EQ(RunConfig::checkValueText("diagnostics.store_prior_every", "-5"),
            "diagnostics.store_prior_every = -5: expected an integer in [0, 2147483647]");
  EXPECT_EQ(RunConfig::checkValueText("lm.max_iterations", "1e12"),
            "lm.max_iterations = 1000000000000: expected an integer in [1, 1000]");
  EXPECT_NE(RunConfig::checkValueText("lm.threads", "four"), "");
  EXPECT_THROW(RunConfig::checkValueText("lm.no_such_key", "1"), std::logic_error);
}

// A flag takes TOML's true or false only: an integer (enabled = 1) is an input error naming the
// key, never a silent conversion (issue #38).
TEST(ConfigValidation, FlagsTakeTrueOrFalseNotIntegers) {
  for (const char* text :
       {"[diagnostics]\nenabled = 1\n", "[diagnostics]\nenabled = 0\n",
        "[lm]\nlandmark_damping = 1.0\n", "[lm]\nlandmark_damping = \"true\"\n"}) {
    RunConfig config;
    try {
      config.loadTomlString(text, "flags.toml");
      FAIL() << "accepted " << text;
    } catch (const InputError& e) {
      EXPECT_TRUE(contains(e.what(), "flags.toml:2")) << e.what();
      EXPECT_TRUE(contains(e.what(), "expected true or false")) << e.what();
    }
  }
  RunConfig config;
  config.loadTomlString("[diagnostics]\nenabled = false\n", "flags.toml");
  EXPECT_FALSE(config.diagnostics.enabled);
}

// lm.stop_rule (issue #21): the two rule names parse and print back; anything else is an input
// error naming the file, line, key and the accepted names.
TEST(ConfigValidation, StopRuleIsMarglabOrBasalt) {
  RunConfig config;
  EXPECT_EQ(config.estimator.lm_stop_rule, LmStopRule::kMarglab);
  config.loadTomlString("[lm]\nstop_rule = \"basalt\"\n", "basalt.toml");
  EXPECT_EQ(config.estimator.lm_stop_rule, LmStopRule::kBasalt);
  RunConfig round_trip;
  round_trip.loadTomlString(config.toToml(), "round_trip.toml");
  EXPECT_EQ(round_trip.estimator.lm_stop_rule, LmStopRule::kBasalt);
  try {
    RunConfig bad;
    bad.loadTomlString("[lm]\nstop_rule = \"ceres\"\n", "cfg.toml");
    FAIL() << "accepted stop_rule = \"ceres\"";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "cfg.toml");
    EXPECT_EQ(e.line(), 2);
    EXPECT_TRUE(contains(e.what(), "expected \"marglab\" or \"basalt\" for lm.stop_rule"))
        << e.what();
  }
}

// A window file records the estimator's settings; one written before they were split from the run's
// config holds the whole config, whose pipeline sections are passed over. Unknown keys of the
// estimator's own sections stay errors.
TEST(ConfigValidation, EstimatorSettingsReadTheirSectionsOfAWholeRunConfig) {
  RunConfig config;
  config.estimator.lm_threads = 3;
  config.estimator.marg_strategy = MargStrategy::kNfr;
  config.frontend.window_px = 11;
  config.diagnostics.enabled = false;
  EstimatorSettings settings;
  settings.loadTomlString(config.toToml(), "window.win [config]");
  EXPECT_EQ(settings.lm_threads, 3);
  EXPECT_EQ(settings.marg_strategy, MargStrategy::kNfr);
  EXPECT_EQ(settings.toToml().find("[frontend]"), std::string::npos) << settings.toToml();
  std::istringstream lines(settings.toToml());
  for (std::string line; std::getline(lines, line);) {
    EXPECT_NE(config.toToml().find(line), std::string::npos) << line;  // the same keys and values
  }
  EXPECT_THROW(settings.loadTomlString("[lm]\nthreadz = 2\n", "window.win [config]"), InputError);
  EXPECT_EQ(config.reporting().shadow_prior, false);
  EXPECT_EQ(config.reporting().inconsistent_px, config.failure.inconsistent_px);
}

}  // namespace
}  // namespace marglab
