// One typed run (core/pipeline/run_spec.h), validated once before any work (runProblems): a sweep
// refuses at plan time — `--dry-run` included — every run `marglab run` would refuse, naming the
// run and the reason, and starts none; `--set` reaches every config key and is recorded; a run
// repeated from its spec gives the same numbers.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/common/source_dir.h"
#include "core/data/sequence.h"
#include "core/io/hdf5.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::quote;
using test::runCli;

class RunSpecTest : public test::TempDirTest {
 protected:
  // A sweep file of one group with `body` (datasets, variants, ...) in the temporary folder.
  fs::path sweepFile(const std::string& body) const {
    const fs::path file = dir_ / "sweep.toml";
    std::ofstream(file) << "name = \"s\"\n[[group]]\nname = \"g\"\n" << body;
    return file;
  }

  // `sweep FILE` (dry run and real) refuses with exit 1 naming the run and `reason`; no run starts.
  void expectPlanRefuses(const std::string& body, const std::string& run,
                         const std::string& reason) const {
    const fs::path file = sweepFile(body);
    const fs::path out = dir_ / "out";
    for (const std::string extra : {" --dry-run", ""}) {
      const auto result = runCli("sweep " + quote(file) + extra + " -o " + quote(out));
      EXPECT_EQ(result.exit_code, 1) << extra << "\n" << result.output;
      EXPECT_NE(result.output.find("run " + run), std::string::npos) << result.output;
      EXPECT_NE(result.output.find(reason), std::string::npos) << reason << "\n" << result.output;
      EXPECT_FALSE(fs::exists(out / "index.csv")) << extra;
      EXPECT_FALSE(fs::exists(out / "tracks")) << extra;
    }
  }

  // An ASL data.csv with every timestamp moved by 10^12 ns (file names kept).
  static void shiftTimestamps(const fs::path& csv) {
    std::ifstream in(csv);
    std::string line, text;
    while (std::getline(in, line)) {
      const std::size_t comma = line.find(',');
      if (!line.empty() && line[0] != '#' && comma != std::string::npos) {
        line = std::to_string(std::stoll(line.substr(0, comma)) + 1000000000000LL) +
               line.substr(comma);
      }
      text += line + "\n";
    }
    in.close();
    std::ofstream(csv) << text;
  }

  std::string rootAttribute(const fs::path& results, const std::string& name) const {
    return h5::File::openReadOnly(results.string()).attr<std::string>(name);
  }
};

TEST_F(RunSpecTest, SweepRefusesAtPlanTimeWhatRunRefuses) {
  expectPlanRefuses(
      "datasets = [\"kitti/05\"]\nvariants = [\"ns-qr-sqrt-f32\"]\nframes = 5\n"
      "[group.config]\nmarginalization = { psd_hessian_prior = true }\n",
      "g__kitti-05__ns-qr-sqrt-f32__s1", "expected a Hessian prior storage");
  expectPlanRefuses(
      "datasets = [\"kitti/05\"]\nvariants = [\"ns-qr-sqrt-f32\"]\nframes = 5\n"
      "args = [\"--qr-threshold-mode\", \"relative\"]\n"
      "[group.config]\nmarginalization = { qr_threshold = 5 }\n",
      "g__kitti-05__ns-qr-sqrt-f32__s1", "expected a relative threshold in [0, 1)");
  expectPlanRefuses(
      "datasets = [\"euroc/MH_01_easy\"]\nvariants = [\"ns-qr-sqrt-f32\"]\nframes = 5\n"
      "args = [\"--imu\", \"real\"]\n",
      "g__euroc-MH_01_easy__ns-qr-sqrt-f32__s1", "has no real IMU recording");
  expectPlanRefuses("datasets = [\"tumvi/corridor2\"]\nvariants = [\"ns-qr-sqrt-f32\"]\n",
                    "g__tumvi-corridor2__ns-qr-sqrt-f32__s1", "has no trajectory to simulate from");
  expectPlanRefuses(
      "datasets = [\"kitti/05\"]\nvariants = [\"ns-qr-sqrt-f32\"]\nframes = 5\n"
      "args = [\"--dump-windows\", \"2\", \"--dump-dir\", \"/proc/nope/windows\"]\n",
      "g__kitti-05__ns-qr-sqrt-f32__s1", "--dump-dir /proc/nope/windows: cannot create the folder");
  expectPlanRefuses(
      "datasets = [\"kitti/05\"]\nvariants = [\"ns-qr-sqrt-f32\"]\nframes = 20\n"
      "args = [\"--dump-windows\", \"500\"]\n",
      "g__kitti-05__ns-qr-sqrt-f32__s1", "--dump-windows 500: the run has 20 frames");
}

// A track file of another sequence, and a user's folder without an IMU with --imu real: refused
// before any image is tracked.
TEST_F(RunSpecTest, SweepRefusesInputsOfAnotherSequenceBeforeAnyWork) {
  const fs::path tracks = dir_ / "k05.h5";
  const auto simulate =
      runCli("datasets simulate --dataset kitti/05 --frames 5 -o " + quote(tracks));
  ASSERT_EQ(simulate.exit_code, 0) << simulate.output;
  expectPlanRefuses(
      "datasets = [\"kitti/10\"]\nvariants = [\"ns-qr-sqrt-f32\"]\nframes = 5\n"
      "args = [\"--tracks\", " +
          quote(tracks) + "]\n",
      "g__kitti-10__ns-qr-sqrt-f32__s1", "k05.h5");
  // A recording of the user's own: V1_01's images at other timestamps, so that no shipped sequence
  // supplies its ground truth or IMU.
  const fs::path folder = dir_ / "myrecording";
  fs::copy(fs::path(datasetsRoot()) / "euroc" / "V1_01_easy_images", folder,
           fs::copy_options::recursive);
  for (const char* cam : {"cam0", "cam1"}) shiftTimestamps(folder / "mav0" / cam / "data.csv");
  expectPlanRefuses("datasets = [\"" + folder.string() +
                        "\"]\nvariants = [\"ns-qr-sqrt-f32\"]\nfrontend = \"images\"\n"
                        "args = [\"--mode\", \"vio\", \"--imu\", \"real\"]\n",
                    "g__", "has no real IMU recording");
}

TEST_F(RunSpecTest, SetReachesEveryKeyAndIsRecorded) {
  const fs::path out = dir_ / "x.h5";
  const auto ok = runCli(
      "run --dataset kitti/05 --variant ns-qr-sqrt-f64 --frames 5 --set lm.max_iterations=3 "
      "--set marginalization.qr_threshold_mode=relative -o " +
      quote(out));
  ASSERT_EQ(ok.exit_code, 0) << ok.output;
  const std::string config = rootAttribute(out, "config_toml");
  EXPECT_NE(config.find("max_iterations = 3"), std::string::npos) << config;
  EXPECT_NE(config.find("qr_threshold_mode = 'relative'"), std::string::npos) << config;
  const std::string spec = rootAttribute(out, "run_spec");
  EXPECT_NE(spec.find("'lm.max_iterations=3'"), std::string::npos) << spec;

  const std::string run = "run --dataset kitti/05 --variant ns-qr-sqrt-f64 --frames 5 -o " +
                          quote(dir_ / "y.h5") + " --set ";
  const auto unknown = runCli(run + "lm.max_iteration=3");
  EXPECT_EQ(unknown.exit_code, 2) << unknown.output;
  EXPECT_NE(unknown.output.find("--set lm.max_iteration=3: unknown key lm.max_iteration"),
            std::string::npos)
      << unknown.output;
  const auto range = runCli(run + "lm.max_iterations=0");
  EXPECT_EQ(range.exit_code, 2) << range.output;
  EXPECT_NE(range.output.find("lm.max_iterations = 0: expected an integer in [1, 1000]"),
            std::string::npos)
      << range.output;
  const auto malformed = runCli(run + "max_iterations");
  EXPECT_EQ(malformed.exit_code, 2) << malformed.output;
  EXPECT_NE(malformed.output.find("expected section.key=value"), std::string::npos)
      << malformed.output;
  EXPECT_FALSE(fs::exists(dir_ / "y.h5"));
}

// A relation between keys is refused before the sequence is simulated, naming both keys.
TEST_F(RunSpecTest, RelationErrorIsRefusedBeforeAnyWork) {
  const auto result = runCli(
      "run --dataset euroc/MH_01_easy --variant ns-qr-sqrt-f32 --set "
      "marginalization.qr_threshold_mode=relative --set marginalization.qr_threshold=5 -o " +
      quote(dir_ / "x.h5"));
  EXPECT_EQ(result.exit_code, 2) << result.output;
  EXPECT_NE(result.output.find("--set: marginalization.qr_threshold = 5 with qr_threshold_mode"),
            std::string::npos)
      << result.output;
  EXPECT_FALSE(fs::exists(dir_ / "x.h5"));
}

// diagnostics.marg_rounding: refused before any work where it cannot measure (not sc-sq); on a
// VO-32 run, one CSV row per marginalization beside the results file.
TEST_F(RunSpecTest, MargRoundingIsRefusedWhereItCannotMeasureAndWritesItsCsv) {
  const auto refused = runCli(
      "run --dataset kitti/10 --variant ns-qr-sqrt-f32 --frames 5 --set "
      "diagnostics.marg_rounding=true -o " +
      quote(dir_ / "x.h5"));
  EXPECT_EQ(refused.exit_code, 2) << refused.output;
  EXPECT_NE(refused.output.find("--set: diagnostics.marg_rounding = true with variant "
                                "ns-qr-sqrt-f32"),
            std::string::npos)
      << refused.output;
  EXPECT_FALSE(fs::exists(dir_ / "x.h5"));
  const auto ok = runCli(
      "run --dataset kitti/10 --variant sc-sc-sq-f32 --frames 30 --set "
      "diagnostics.marg_rounding=true -o " +
      quote(dir_ / "y.h5"));
  ASSERT_EQ(ok.exit_code, 0) << ok.output;
  std::ifstream csv(dir_ / "y.rounding.csv");
  std::string header, line;
  ASSERT_TRUE(std::getline(csv, header));
  EXPECT_EQ(header.rfind("frame_index,n,n_marg,n_landmarks,total_rel,", 0), 0u) << header;
  int rows = 0;
  while (std::getline(csv, line)) ++rows;
  // One row per marginalization of the window's prior, at most one per frame; /marg counts the
  // events of the shadow prior once it is not empty, so not more.
  EXPECT_LE(rows, 30);
  EXPECT_GE(rows, h5::File::openReadOnly((dir_ / "y.h5").string())
                      .openGroup("summary")
                      .attr<std::int64_t>("n_marg"));
  EXPECT_GT(rows, 10);
}

// The results file records its spec; run from it (-o elsewhere), the numbers are the same bit for
// bit.
TEST_F(RunSpecTest, RunRepeatedFromItsSpecIsBitIdentical) {
  const fs::path first = dir_ / "first.h5";
  const auto run = runCli(
      "run --dataset kitti/05 --variant sc-sc-sq-f32 --frames 40 --seed 3 --set "
      "lm.max_iterations=4 "
      "--threads 1 -o " +
      quote(first));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const fs::path spec = dir_ / "first.spec.toml";
  std::ofstream(spec) << rootAttribute(first, "run_spec");
  const fs::path second = dir_ / "second.h5";
  const auto again = runCli("run --spec " + quote(spec) + " -o " + quote(second));
  ASSERT_EQ(again.exit_code, 0) << again.output;
  const auto compare =
      test::runShell("/usr/bin/python3 '" + std::string(sourceDir()) +
                     "/tools/scripts/compare_runs.py' " + quote(first) + " " + quote(second));
  EXPECT_EQ(compare.exit_code, 0) << compare.output;
  EXPECT_NE(compare.output.find("SAME"), std::string::npos) << compare.output;
  EXPECT_EQ(rootAttribute(first, "config_toml"), rootAttribute(second, "config_toml"));

  const auto beside = runCli("run --spec " + quote(spec) + " --frames 3 -o " + quote(second));
  EXPECT_EQ(beside.exit_code, 2) << beside.output;
  EXPECT_NE(beside.output.find("--frames cannot be given beside it (only -o)"), std::string::npos)
      << beside.output;
}

// A sweep group's `set` reaches the run's config; the sweep's child ran the spec file beside the
// index, and running that file again gives the same numbers.
TEST_F(RunSpecTest, SweepRunRepeatedFromItsSpecFileIsBitIdentical) {
  const fs::path file = sweepFile(
      "datasets = [\"kitti/05\"]\nvariants = [\"sc-sc-sq-f32\"]\nframes = 30\n"
      "set = [\"lm.max_iterations=4\"]\n");
  const fs::path out = dir_ / "out";
  const auto sweep = runCli("sweep " + quote(file) + " -o " + quote(out));
  ASSERT_EQ(sweep.exit_code, 0) << sweep.output;
  const std::string id = "g__kitti-05__sc-sc-sq-f32__s1";
  const fs::path results = out / "runs" / (id + ".h5");
  EXPECT_NE(rootAttribute(results, "config_toml").find("max_iterations = 4"), std::string::npos);
  EXPECT_NE(test::readText(out / "logs" / (id + ".log"))
                .find("# run as: marglab run --spec runs/" + id + ".spec.toml"),
            std::string::npos);
  const fs::path again = dir_ / "again.h5";
  const auto rerun = test::runShell("cd " + quote(out) + " && '" + test::cliPath() +
                                    "' run --spec runs/" + id + ".spec.toml -o " + quote(again));
  ASSERT_EQ(rerun.exit_code, 0) << rerun.output;
  const auto compare =
      test::runShell("/usr/bin/python3 '" + std::string(sourceDir()) +
                     "/tools/scripts/compare_runs.py' " + quote(results) + " " + quote(again));
  EXPECT_EQ(compare.exit_code, 0) << compare.output;
}

}  // namespace
}  // namespace marglab
