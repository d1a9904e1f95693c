// `marglab run` refuses meaningless settings before it starts (docs/design.md §9; issue #18
// items 5, 6, 11): a bad value in a --config file exits 1 naming FILE:LINE, the key, the value
// and the range; a bad command-line value exits 2 naming the option. Nothing is written, and
// nothing is reported as a numerical failure of the estimator. All fail before any simulation.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/cli_runner.h"
#include "common/temp_dir.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::runCli;

class ConfigValuesCliTest : public test::TempDirTest {
 protected:
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string config(const std::string& text) const {
    const std::string file = path("cfg.toml");
    std::ofstream(file) << text;
    return file;
  }
  // `marglab run` on KITTI 10 with extra arguments; the output must never appear.
  test::CliResult run(const std::string& extra) const {
    const auto result = runCli("run --dataset kitti/10 --variant ns-qr-sqrt-f32 --frames 5 " +
                               extra + " -o '" + path("r.h5") + "'");
    EXPECT_FALSE(fs::exists(path("r.h5"))) << extra;
    EXPECT_EQ(result.output.find("FAILED"), std::string::npos) << result.output;
    return result;
  }
};

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST_F(ConfigValuesCliTest, BadConfigFileValuesExitOneNamingFileLineKeyAndRange) {
  struct Case {
    const char* toml;
    const char* message;
  };
  for (const Case& c : {
           Case{"[lm]\nmax_iterations = 1e12\n",
                "lm.max_iterations = 1000000000000: expected an integer in [1, 1000]"},
           Case{"[lm]\nmax_iterations = 0\n", "lm.max_iterations = 0"},
           Case{"[residuals]\nhuber_px = 0\n",
                "residuals.huber_px = 0: expected a finite number > 0"},
           Case{"[residuals]\nobs_std_px = inf\n", "residuals.obs_std_px = inf"},
           Case{"[residuals]\nobs_std_px = nan\n", "residuals.obs_std_px = nan"},
           Case{"[residuals]\nhuber_px = -1\n", "residuals.huber_px = -1"},
           Case{"[gauge]\nprior_weight = -1\n", "gauge.prior_weight = -1"},
           Case{"[keyframes]\nconnected_ratio = 5\n",
                "keyframes.connected_ratio = 5: expected a finite number in (0, 1]"},
           Case{"[window]\nmax_kfs = 0\n",
                "window.max_kfs = 0: expected an integer in [1, 1000000]"},
           Case{"[lm]\nthreads = 10000\n", "lm.threads = 10000: expected an integer in [1, 256]"},
       }) {
    const std::string file = config(c.toml);
    const auto result = run("--config '" + file + "'");
    EXPECT_EQ(result.exit_code, 1) << c.toml << result.output;
    EXPECT_TRUE(contains(result.output, file + ":2: " + c.message)) << c.toml << result.output;
  }
}

TEST_F(ConfigValuesCliTest, RelationBetweenKeysOfTheEffectiveConfig) {
  const std::string file = config("[lm]\nlambda_min = 10\nlambda_max = 1\n");
  const auto lambdas = run("--config '" + file + "'");
  EXPECT_EQ(lambdas.exit_code, 1) << lambdas.output;
  EXPECT_TRUE(contains(lambdas.output, file + ":2: ")) << lambdas.output;
  EXPECT_TRUE(contains(lambdas.output, "expected lambda_min <= lambda_init <= lambda_max"))
      << lambdas.output;
  // The file's relative mode and the command line's threshold together are meaningless: the
  // option is named (usage error).
  const std::string relative = config("[marginalization]\nqr_threshold_mode = \"relative\"\n");
  const auto qr = run("--config '" + relative + "' --qr-threshold 2");
  EXPECT_EQ(qr.exit_code, 2) << qr.output;
  EXPECT_TRUE(contains(qr.output, "--qr-threshold: marginalization.qr_threshold = 2")) << qr.output;
}

TEST_F(ConfigValuesCliTest, BadCommandLineValuesExitTwoNamingTheOption) {
  struct Case {
    const char* args;
    const char* message;
  };
  for (const Case& c : {
           Case{"--threads 10000", "lm.threads = 10000: expected an integer in [1, 256]"},
           Case{"--threads 0", "lm.threads = 0: expected an integer in [1, 256]"},
           Case{"--qr-threshold nan", "marginalization.qr_threshold = nan"},
           Case{"--store-prior-every -5", "diagnostics.store_prior_every = -5"},
           Case{"--seed -1", "expected an integer in [0, 18446744073709551615]"},
           Case{"--seed 18446744073709551616", "expected an integer in [0, 18446744073709551615]"},
           Case{"--frames -3", "expected the number of frames"},
       }) {
    const auto result = run(c.args);
    EXPECT_EQ(result.exit_code, 2) << c.args << "\n" << result.output;
    EXPECT_TRUE(contains(result.output, c.message)) << c.args << "\n" << result.output;
    // No 309-digit range of CLI::PositiveNumber.
    EXPECT_LT(result.output.size(), 400u) << result.output;
  }
}

// A sweep whose args or merged config are meaningless fails validation before any run.
TEST_F(ConfigValuesCliTest, SweepValidationRejectsBadValuesBeforeAnyRun) {
  struct Case {
    const char* group;
    int line;
    const char* message;
  };
  for (const Case& c : {
           Case{"args = [\"--threads\", \"10000\"]\n", 6, "lm.threads = 10000"},
           Case{"config = { lm = { max_iterations = 1e12 } }\n", 6,
                "lm.max_iterations = 1000000000000"},
       }) {
    const std::string file = path("s.toml");
    std::ofstream(file) << "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\"]\n"
                        << "variants = [\"ns-qr-sqrt-f32\"]\n"
                        << c.group;
    const auto result = runCli("sweep '" + file + "' --out '" + path("out") + "'");
    EXPECT_EQ(result.exit_code, 1) << result.output;
    EXPECT_TRUE(contains(result.output, "s.toml:" + std::to_string(c.line) + ":")) << result.output;
    EXPECT_TRUE(contains(result.output, c.message)) << result.output;
    EXPECT_FALSE(fs::exists(path("out")));
  }
}

}  // namespace
}  // namespace marglab
