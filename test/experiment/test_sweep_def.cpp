// Sweep definitions: expansion of datasets × variants × seeds × overrides into runs, config
// layering, and rejection of malformed files with the line of the offending key, before any run.

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>

#include <filesystem>
#include <fstream>

#include "common/cli_runner.h"
#include "core/common/error.h"
#include "core/estimator/variant.h"
#include "core/experiment/sweep_def.h"
#include "core/experiment/sweep_index.h"
#include "core/pipeline/run_config.h"

namespace marglab::experiment {
namespace {

namespace fs = std::filesystem;

SweepPlan parse(const std::string& text) { return parseSweep(text, "sweep.toml", "/nonexistent"); }

TEST(SweepDefinition, ExpandsTheCrossProductWithStableIds) {
  const SweepPlan plan = parse(R"(
name = "demo"
[[group]]
name = "vo"
datasets = ["kitti/10", "kitti/04"]
variants = ["headline", "sc-qr-sqrt-f32", "ns-qr-sqrt-f32"]
seeds = [1, 7]
frames = 30
[[group.override]]
name = "abs"
[[group.override]]
name = "rel"
args = ["--qr-threshold-mode", "relative"]
config = { lm = { max_iterations = 5 } }
)");
  EXPECT_EQ(plan.name, "demo");
  // 2 datasets × 5 distinct variants (ns-qr-sqrt-f32 is in "headline") × 2 seeds × 2 overrides.
  ASSERT_EQ(plan.runs.size(), 2u * 5u * 2u * 2u);
  const PlannedRun& first = plan.runs.front();
  EXPECT_EQ(first.id, "vo__kitti-10__ns-qr-sqrt-f64__s1__abs");
  EXPECT_EQ(first.frames, 30);
  EXPECT_TRUE(first.extra_args.empty());
  EXPECT_TRUE(first.config_toml.empty());
  const PlannedRun& second = plan.runs[1];
  EXPECT_EQ(second.id, "vo__kitti-10__ns-qr-sqrt-f64__s1__rel");
  EXPECT_EQ(second.extra_args, (std::vector<std::string>{"--qr-threshold-mode", "relative"}));
  RunConfig config;
  config.loadTomlString(second.config_toml, "merged");
  EXPECT_EQ(config.estimator.lm_max_iterations, 5);
  const std::vector<std::string> args = runArguments(second, "runs/x.h5", "configs/x.toml");
  EXPECT_EQ(args,
            (std::vector<std::string>{"run", "--dataset", "kitti/10", "--variant", "ns-qr-sqrt-f64",
                                      "--seed", "1", "--frames", "30", "--config", "configs/x.toml",
                                      "--qr-threshold-mode", "relative", "-o", "runs/x.h5"}));
}

TEST(SweepDefinition, OverrideConfigWinsOverGroupConfigKeyByKey) {
  const SweepPlan plan = parse(R"(
name = "layers"
[[group]]
name = "g"
datasets = ["kitti/10"]
variants = ["ns-qr-sqrt-f64"]
[group.config]
lm = { max_iterations = 4, lambda_init = 1e-3 }
[[group.override]]
name = "o"
config = { lm = { max_iterations = 9 } }
)");
  ASSERT_EQ(plan.runs.size(), 1u);
  RunConfig config;
  config.loadTomlString(plan.runs[0].config_toml, "merged");
  EXPECT_EQ(config.estimator.lm_max_iterations, 9);
  EXPECT_EQ(config.estimator.lambda_init, 1e-3);
}

TEST(SweepDefinition, VariantSetsMatchThePapersColumns) {
  EXPECT_EQ(expandVariantEntry("paper").size(), 10u);
  EXPECT_EQ(expandVariantEntry("headline"),
            (std::vector<std::string>{"ns-qr-sqrt-f64", "ns-qr-sqrt-f32", "sc-sc-sq-f64",
                                      "sc-sc-sq-f32"}));
  const auto ablation = expandVariantEntry("ablation");
  ASSERT_EQ(ablation.size(), 8u);
  for (const std::string& v : ablation) EXPECT_NE(v.find("-sqrt-"), std::string::npos) << v;
  EXPECT_THROW(expandVariantEntry("ns-qr-sq-f32"), UsageError);  // qr requires sqrt storage
  // Issue #31 §3's set: every name parses back to itself.
  const auto preconditioned = expandVariantEntry("preconditioned");
  ASSERT_EQ(preconditioned.size(), 5u);
  for (const std::string& v : preconditioned) EXPECT_EQ(Variant::parse(v).name(), v);
}

struct Malformed {
  const char* name;
  const char* text;
  int line;
  const char* message;
};

class MalformedSweep : public ::testing::TestWithParam<Malformed> {};

TEST_P(MalformedSweep, IsRejectedWithTheLineNamed) {
  const Malformed& m = GetParam();
  try {
    parse(m.text);
    FAIL() << "accepted:\n" << m.text;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "sweep.toml");
    EXPECT_EQ(e.line(), m.line) << e.what();
    EXPECT_NE(std::string(e.what()).find(m.message), std::string::npos) << e.what();
  }
}

const char* const kHead = "name = \"bad\"\n[[group]]\nname = \"g\"\n";  // lines 1-3

INSTANTIATE_TEST_SUITE_P(
    Files, MalformedSweep,
    ::testing::Values(
        Malformed{"UnknownKey",
                  "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\"]\n"
                  "variants = [\"headline\"]\nframs = 30\n",
                  6, "unknown key 'frams'"},
        Malformed{"UnknownTopLevelKey", "name = \"bad\"\njobs = 3\n", 2, "unknown key 'jobs'"},
        Malformed{"UnknownVariant",
                  "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\"]\n"
                  "variants = [\"ns-qr-sqrt-f32\",\n  \"ns-qr-sqrt-f16\"]\n",
                  6, "precision"},
        Malformed{"MissingDataset",
                  "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\",\n"
                  "  \"kitti/42\"]\nvariants = [\"headline\"]\n",
                  5, "unknown dataset 'kitti/42'"},
        Malformed{"UnknownConfigKey",
                  "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\"]\n"
                  "variants = [\"headline\"]\n[group.config]\nlm = { max_iter = 3 }\n",
                  7, "unknown key lm.max_iter"},
        Malformed{"ReservedRunOption",
                  "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\"]\n"
                  "variants = [\"headline\"]\nargs = [\"--seed\", \"3\"]\n",
                  6, "--seed is set by the sweep"},
        Malformed{"DuplicateRun",
                  "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\", "
                  "\"kitti/10\"]\nvariants = [\"headline\"]\n",
                  2, "planned twice"},
        Malformed{"NegativeFrames",
                  "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\"]\n"
                  "variants = [\"headline\"]\n\nframes = -4\n",
                  7, "frames must be"},
        Malformed{"MissingVariants",
                  "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\"]\n", 2,
                  "needs variants"},
        Malformed{"UnknownFrontend",
                  "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\"]\n"
                  "variants = [\"headline\"]\nfrontend = \"klt\"\n",
                  6, "frontend must be"},
        Malformed{"FrontendTwice",
                  "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\"]\n"
                  "variants = [\"headline\"]\nargs = [\"--frontend\", \"images\"]\n"
                  "frontend = \"images\"\n",
                  7, "must not hold --frontend"},
        Malformed{"TomlSyntax", "name = \"bad\"\n[[group]\n", 2, ""}),
    [](const auto& info) { return std::string(info.param.name); });

// Issue 38 (low): user folders a/06 and a-06 have one slug (tmp-…-a-06); in one group they were
// "planned twice" (as if listed twice), in two groups accepted, sharing logs and track files.
// The error names both datasets and the slug.
TEST(SweepDefinition, DatasetsWithTheSameSlugAreRefusedNamingBoth) {
  const fs::path base = fs::temp_directory_path() / ("marglab_slug_" + std::to_string(::getpid()));
  fs::create_directories(base / "a" / "06");
  fs::create_directories(base / "a-06");
  const std::string a = (base / "a" / "06").string(), b = (base / "a-06").string();
  const std::string same_group =
      "name = \"s\"\n[[group]]\nname = \"g\"\ndatasets = [\"a/06\",\n  \"a-06\"]\n"
      "variants = [\"headline\"]\n";
  const std::string two_groups =
      "name = \"s\"\n[[group]]\nname = \"g\"\ndatasets = [\"a/06\"]\nvariants = [\"headline\"]\n"
      "[[group]]\nname = \"h\"\ndatasets = [\"a-06\"]\nvariants = [\"headline\"]\n";
  for (const auto& [text, line] : {std::pair{same_group, 5}, std::pair{two_groups, 8}}) {
    SCOPED_TRACE(text);
    try {
      parseSweep(text, "sweep.toml", base.string());
      ADD_FAILURE() << "accepted";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_EQ(e.line(), line) << what;
      EXPECT_NE(what.find("datasets '" + a + "' (line 4) and '" + b + "' have the same slug '" +
                          slug(a) + "'"),
                std::string::npos)
          << what;
      EXPECT_EQ(what.find("planned twice"), std::string::npos) << what;
    }
  }
  fs::remove_all(base);
}

// frontend = "images": every run reads the track file the runner writes once per dataset.
TEST(SweepDefinition, ImagesFrontendRunsReadOneTrackFilePerDataset) {
  const SweepPlan plan = parse(R"(
name = "real"
[[group]]
name = "img"
datasets = ["euroc/V1_01_easy_images"]
variants = ["ns-qr-sqrt-f32", "ns-qr-sqrt-f64"]
frontend = "images"
[[group]]
name = "sim"
datasets = ["euroc/V1_01_easy_images"]
variants = ["ns-qr-sqrt-f32"]
frontend = "simulated"
)");
  ASSERT_EQ(plan.runs.size(), 3u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(plan.runs[i].frontend, FrontendKind::kImages);
    EXPECT_EQ(sweepTrackFile(plan.runs[i]), "tracks/euroc-V1_01_easy_images.h5");
    const std::vector<std::string> args = runArguments(plan.runs[i], "runs/x.h5", "");
    const auto it = std::find(args.begin(), args.end(), "--tracks");
    ASSERT_NE(it, args.end());
    EXPECT_EQ(*(it + 1), "tracks/euroc-V1_01_easy_images.h5");
  }
  const std::vector<std::string> sim = runArguments(plan.runs[2], "runs/y.h5", "");
  const auto it = std::find(sim.begin(), sim.end(), "--frontend");
  ASSERT_NE(it, sim.end());
  EXPECT_EQ(*(it + 1), "simulated");
}

TEST(SweepDefinition, RunOptionsAreCheckedByTheGivenChecker) {
  ParseOptions options;
  options.check_run_args = [](const std::vector<std::string>& args) {
    return args.front() == "--bogus" ? std::string("--bogus is not an option") : std::string();
  };
  const std::string text = std::string(kHead) +
                           "datasets = [\"kitti/10\"]\nvariants = [\"headline\"]\n"
                           "args = [\"--bogus\"]\n";
  try {
    parseSweep(text, "s.toml", "/", options);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 6);
    EXPECT_NE(std::string(e.what()).find("--bogus is not an option"), std::string::npos);
  }
}

// Through the CLI: the real `run` verb checks the options, and nothing is created or run.
TEST(SweepCli, MalformedFileStartsNoRun) {
  const fs::path dir =
      fs::temp_directory_path() / ("marglab_sweep_bad_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path file = dir / "bad.toml";
  std::ofstream(file) << kHead << "datasets = [\"kitti/10\"]\nvariants = [\"headline\"]\n"
                      << "args = [\"--no-such-option\"]\n";
  const auto result =
      test::runCli("sweep '" + file.string() + "' --out '" + (dir / "out").string() + "'");
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find("bad.toml:6:"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("--no-such-option"), std::string::npos) << result.output;
  EXPECT_FALSE(fs::exists(dir / "out"));
  fs::remove_all(dir);
}

TEST(SweepIndex, CsvRoundTripKeepsCommasQuotesAndNewlines) {
  const fs::path path =
      fs::temp_directory_path() / ("marglab_index_" + std::to_string(getpid()) + ".csv");
  IndexRow row;
  row.set("id", "a");
  row.set("reason", "solve failed, \"twice\"\nsecond line");
  row.setNumber("ate_rmse", 0.1 + 0.2);
  writeIndex(path.string(), {row, row});
  const auto rows = readIndex(path.string());
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[1].get("reason"), row.get("reason"));
  EXPECT_EQ(rows[1].number("ate_rmse"), 0.1 + 0.2);  // %.17g round-trips exactly
  EXPECT_TRUE(std::isnan(rows[1].number("t_opt_total_s")));
  fs::remove(path);
}

}  // namespace
}  // namespace marglab::experiment
