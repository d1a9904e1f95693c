// `marglab datasets simulate` through the real binary (test::cliPath()): exit codes, printed
// statistics, and the track file it writes.

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "common/cli_runner.h"
#include "core/sim/track_io.h"
#include "data/data_test_utils.h"
#include "test_paths.h"

namespace marglab {
namespace {

using test::CliResult;
using test::runCli;

TEST(CliSimulate, ShortPrefixWritesTracksAndPrintsStatistics) {
  test::TempDir dir;
  const std::string path = dir.file("mh01.h5");
  const CliResult result = runCli(
      "datasets simulate --dataset euroc/MH_01_easy --seed 3 --frames 100 -o '" + path + "'");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  for (const char* line :
       {"frames              100\n", "features per frame  mean ", "track length ", "stereo share ",
        "outlier share ", "simulation time "}) {
    EXPECT_NE(result.output.find(line), std::string::npos) << line << "\n" << result.output;
  }
  const TrackStream stream = readTrackFile(path);
  EXPECT_EQ(stream.frames.size(), 100u);
  EXPECT_EQ(stream.sequence, "euroc/MH_01_easy");
  EXPECT_EQ(stream.seed, 3u);
  EXPECT_FALSE(stream.landmarks_w.empty());

  // Text output, noise-free, same seed: the same tracks (ids, stereo matches), exact pixels.
  const std::string text = dir.file("mh01.txt");
  const CliResult exact = runCli(
      "datasets simulate --dataset euroc/MH_01_easy --seed 3 --frames 20 "
      "--no-noise -o '" +
      text + "'");
  ASSERT_EQ(exact.exit_code, 0) << exact.output;
  EXPECT_EQ(readTrackFile(text).frames.size(), 20u);
}

// --profile realistic: the stream of the KITTI family's profile, named in the output (fewer stereo
// matches than ideal with the same seed: its stereo failure probability is 0.23 against 0.03); an
// EuRoC sequence takes the EuRoC file; an unknown name is a usage error.
TEST(CliSimulate, RealisticProfile) {
  test::TempDir dir;
  const std::string ideal = dir.file("ideal.h5"), realistic = dir.file("realistic.h5");
  const std::string base = "datasets simulate --dataset kitti/04 --seed 2 --frames 30 ";
  ASSERT_EQ(runCli(base + "-o '" + ideal + "'").exit_code, 0);
  const CliResult r = runCli(base + "--profile realistic -o '" + realistic + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("sim_profiles/realistic_kitti.toml)"), std::string::npos) << r.output;
  const CliResult euroc =
      runCli("datasets simulate --dataset euroc/V1_01_easy --frames 5 --profile realistic -o '" +
             dir.file("euroc.h5") + "'");
  ASSERT_EQ(euroc.exit_code, 0) << euroc.output;
  EXPECT_NE(euroc.output.find("sim_profiles/realistic_euroc.toml)"), std::string::npos)
      << euroc.output;
  auto stereo = [](const TrackStream& s) {
    double n = 0, right = 0;
    for (const TrackFrame& f : s.frames) {
      for (const StereoObservation& o : f.observations) {
        n += 1;
        right += o.has_right ? 1 : 0;
      }
    }
    return right / n;
  };
  EXPECT_GT(stereo(readTrackFile(ideal)), 0.8);
  EXPECT_LT(stereo(readTrackFile(realistic)), stereo(readTrackFile(ideal)) - 0.1);
  EXPECT_EQ(runCli(base + "--profile noisy -o '" + dir.file("x.h5") + "'").exit_code, 2);
}

TEST(CliSimulate, ErrorsAndUsage) {
  test::TempDir dir;
  const CliResult no_gt =
      runCli("datasets simulate --dataset tumvi/corridor2 -o '" + dir.file("x.h5") + "'");
  EXPECT_EQ(no_gt.exit_code, 1) << no_gt.output;
  EXPECT_NE(no_gt.output.find("no trajectory"), std::string::npos) << no_gt.output;
  EXPECT_EQ(runCli("datasets simulate --dataset euroc/MH_01_easy").exit_code, 2);
  // An unknown dataset is an input error, as in `marglab run` (issue #18 item 9).
  EXPECT_EQ(runCli("datasets simulate --dataset euroc/nope -o x.h5").exit_code, 1);
  // The seed is range-checked, not wrapped to 2^64 - 1 (item 11).
  const CliResult seed = runCli("datasets simulate --dataset kitti/10 --seed -1 -o x.h5");
  EXPECT_EQ(seed.exit_code, 2);
  EXPECT_NE(seed.output.find("--seed: -1: expected an integer in [0, 18446744073709551615]"),
            std::string::npos)
      << seed.output;
}

}  // namespace
}  // namespace marglab
