// `marglab datasets list|check` through the real binary (test::cliPath()): exit codes and messages.

#include <gtest/gtest.h>

#include <cstdio>
#include <sstream>

#include "common/cli_runner.h"
#include "core/common/source_dir.h"
#include "data_test_utils.h"
#include "test_paths.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

using test::CliResult;
using test::runCli;

const fs::path kShipped = fs::path(sourceDir()) / "datasets";

TEST(CliDatasets, CheckAllSucceeds) {
  const CliResult result = runCli("datasets check --all");
  EXPECT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("ok    euroc/MH_01_easy"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("ok    tumvi/corridor2          timestamps only"), std::string::npos)
      << result.output;
  EXPECT_EQ(result.output.find("FAIL"), std::string::npos) << result.output;
}

TEST(CliDatasets, CheckReportsCorruptedLineWithFileAndLine) {
  TempDir dir;
  const fs::path seq = dir.path() / "04";
  fs::create_directories(seq);
  fs::copy_file(kShipped / "kitti/04/calib.txt", seq / "calib.txt");
  fs::copy_file(kShipped / "kitti/04/times.txt.gz", seq / "times.txt.gz");
  std::istringstream poses(test::readGz((kShipped / "kitti/04/poses.txt.gz").string()));
  std::string corrupted, line;
  for (int n = 1; std::getline(poses, line); ++n) {
    corrupted += (n == 17 ? line.substr(0, line.size() / 2) : line) + "\n";
  }
  const std::string poses_path = test::writeFile((seq / "poses.txt").string(), corrupted);

  const CliResult result = runCli("datasets check '" + seq.string() + "'");
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find(poses_path + ":17: expected 12 columns"), std::string::npos)
      << result.output;
}

TEST(CliDatasets, ListUsageAndUnknownName) {
  const CliResult list = runCli("datasets list");
  EXPECT_EQ(list.exit_code, 0) << list.output;
  for (const char* name : {"euroc/MH_01_easy", "tumvi/room2", "kitti/10", "5986*"}) {
    EXPECT_NE(list.output.find(name), std::string::npos) << name << "\n" << list.output;
  }
  EXPECT_EQ(runCli("datasets check").exit_code, 2);
  EXPECT_EQ(runCli("datasets").exit_code, 2);
  // An unknown name is an input error, as in `marglab run` (issue #18: it was 1 here, 2 there).
  const CliResult unknown = runCli("datasets check euroc/nope");
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_NE(unknown.output.find("unknown dataset 'euroc/nope': expected a folder or one of"),
            std::string::npos)
      << unknown.output;
}

// A pose moved by 1e5 m passed `check` and made `run --frames 40` take 0.6 GB (issue #18, item 2);
// a 5 MB bad token was echoed in full on stdout and stderr (item 9).
TEST(CliDatasets, CheckRefusesAnImplausiblePoseAndCutsLongTokens) {
  TempDir dir;
  const fs::path seq = dir.path() / "10";
  fs::create_directories(seq);
  fs::copy_file(kShipped / "kitti/10/calib.txt", seq / "calib.txt");
  fs::copy_file(kShipped / "kitti/10/times.txt.gz", seq / "times.txt.gz");
  std::istringstream poses(test::readGz((kShipped / "kitti/10/poses.txt.gz").string()));
  std::string far, garbage, line;
  for (int n = 1; std::getline(poses, line); ++n) {
    std::istringstream in(line);
    std::vector<std::string> v(12);
    for (auto& value : v) in >> value;
    std::string far_row, garbage_row;
    for (int i = 0; i < 12; ++i) {
      far_row += (i ? " " : "") + (n == 500 && i == 3 ? std::string("1e5") : v[i]);
      garbage_row += (i ? " " : "") + (n == 5 && i == 1 ? std::string(500000, 'y') : v[i]);
    }
    far += far_row + "\n";
    garbage += garbage_row + "\n";
  }
  const std::string poses_path = test::writeFile((seq / "poses.txt").string(), far);
  const CliResult result = runCli("datasets check '" + seq.string() + "'");
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find(poses_path +
                               ":500: expected a step of at most 10 m from the previous pose "
                               "(car), found 99"),
            std::string::npos)
      << result.output;

  test::writeFile(poses_path, garbage);
  const CliResult token = runCli("datasets check '" + seq.string() + "'");
  EXPECT_EQ(token.exit_code, 1);
  EXPECT_LT(token.output.size(), 2000u);
  EXPECT_NE(token.output.find(poses_path + ":5: expected a number in column 2, found 'yyyy"),
            std::string::npos)
      << token.output.substr(0, 2000);
  EXPECT_NE(token.output.find("… (500000 bytes)"), std::string::npos);
}

}  // namespace
}  // namespace marglab
