// `marglab ba` through the real binary: a run's HDF5 and JSON, and bad input → exit 1 with no
// results file, bad usage → exit 2.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/common/source_dir.h"
#include "core/io/hdf5.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::runCli;

std::string dubrovnik() {
  return "'" + std::string(sourceDir()) + "/datasets/bal/dubrovnik-3-7-pre.txt'";
}

class BaCli : public test::TempDirTest {};

TEST_F(BaCli, WritesResultsAndJson) {
  const std::string out = (dir_ / "run.h5").string();
  const auto result = runCli("ba --problem " + dubrovnik() +
                             " --solver ns-f32 --iterations 5 --huber 1 --perturb 0.01 --seed 7 "
                             "--json -o '" +
                             out + "'");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const auto json = nlohmann::json::parse(result.output);
  EXPECT_EQ(json["solver"], "ns-f32");
  EXPECT_LT(json["final_cost"].get<double>(), json["initial_cost"].get<double>());
  EXPECT_EQ(json["iterations"].size(), 6u);
  EXPECT_TRUE(json["iterations"][0].contains("time_s"));
  const h5::File file = h5::File::openReadOnly(out);
  EXPECT_EQ(file.attr<std::string>("kind"), "ba");
  EXPECT_EQ(file.attr<std::string>("problem"), "dubrovnik-3-7-pre");
  EXPECT_EQ(file.attr<std::int64_t>("seed"), 7);
  EXPECT_EQ(file.attr<double>("huber_px"), 1.0);
  EXPECT_EQ(file.attr<double>("final_cost"), json["final_cost"].get<double>());
  EXPECT_EQ(file.readVector<double>("iterations/cost").size(), 6u);
  EXPECT_FALSE(file.attr<std::string>("git_sha").empty());
  EXPECT_FALSE(file.attr<std::string>("isa").empty());  // auto: the measured or widest ISA
}

// --isa picks the kernels of ns / sc and is recorded; the same ISA gives the same numbers.
TEST_F(BaCli, IsaIsChosenAndRecorded) {
  const std::string out = (dir_ / "run.h5").string();
  const std::string args = "ba --problem " + dubrovnik() + " --solver sc-f64 --iterations 3 --isa ";
  auto result = runCli(args + "sse2 -o '" + out + "'");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const h5::File file = h5::File::openReadOnly(out);
  EXPECT_EQ(file.attr<std::string>("isa"), "sse2");
  EXPECT_EQ(file.attr<std::string>("isa_choice"), "--isa sse2");
  result = runCli(args + "avx3 -o '" + (dir_ / "other.h5").string() + "'");
  EXPECT_EQ(result.exit_code, 2) << result.output;
  EXPECT_FALSE(fs::exists(dir_ / "other.h5"));
}

TEST_F(BaCli, BadInputExitsOneWithoutAResultsFile) {
  const std::string out = (dir_ / "run.h5").string();
  std::ofstream(dir_ / "bad.txt") << "1 1 2\n0 0 1 2\n0 x 3 4\n0 0 0 0 0 0 500 0 0\n1 2 -5\n";
  const auto result =
      runCli("ba --problem '" + (dir_ / "bad.txt").string() + "' --solver sc-f64 -o '" + out + "'");
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find("bad.txt:3:"), std::string::npos) << result.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(BaCli, BadUsageExitsTwo) {
  const std::string out = (dir_ / "run.h5").string();
  auto result = runCli("ba --problem " + dubrovnik() + " --solver qr-f16 -o '" + out + "'");
  EXPECT_EQ(result.exit_code, 2) << result.output;
  EXPECT_NE(result.output.find("ns-f32, ns-f64"), std::string::npos) << result.output;
  result = runCli("ba --problem " + dubrovnik() + " --solver ns-f64 --huber -1 -o '" + out + "'");
  EXPECT_EQ(result.exit_code, 2) << result.output;
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace marglab
