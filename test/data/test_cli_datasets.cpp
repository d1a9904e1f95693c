// `marglab datasets list|check` through the real binary (test::cliPath()): exit codes and messages.

#include <gtest/gtest.h>

#include <cstdio>
#include <sstream>

#include "test_paths.h"
#include "core/common/source_dir.h"
#include "common/cli_runner.h"
#include "data_test_utils.h"

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
  const CliResult unknown = runCli("datasets check euroc/nope");
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_NE(unknown.output.find("euroc/nope: expected a sequence name"), std::string::npos)
      << unknown.output;
}

}  // namespace
}  // namespace marglab
