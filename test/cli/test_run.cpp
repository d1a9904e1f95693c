// `marglab run` and `marglab eigdump` as a user runs them on the shipped KITTI 10 prefix: the
// results file follows the schema (checked by the independent numpy script), a NaN measurement
// ends the run as `failed` with frame and reason in a complete file, and usage errors exit 2.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/common/source_dir.h"
#include "core/io/results_file.h"
#include "core/linalg/isa.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::runCli;

class RunCliTest : public test::TempDirTest {
 protected:
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
};

TEST_F(RunCliTest, WritesAResultsFileThatFollowsTheSchema) {
  const std::string out = path("k10.h5");
  const auto result = runCli(
      "run --dataset kitti/10 --variant ns-qr-sqrt-f32 --frames 80 "
      "--store-prior-every 5 -o '" +
      out + "'");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  for (const char* line : {"status            ok", "ATE RMSE", "real-time factor", "time opt"}) {
    EXPECT_NE(result.output.find(line), std::string::npos) << line << "\n" << result.output;
  }
  ASSERT_TRUE(fs::exists(out));
  EXPECT_TRUE(fs::exists(path("k10.tum")));

  const ResultsReader reader(out);
  EXPECT_EQ(reader.info().status, "ok");
  EXPECT_EQ(reader.info().metadata.variant, "ns-qr-sqrt-f32");
  EXPECT_NE(reader.info().metadata.config_toml.find("max_kfs = 7"), std::string::npos);
  EXPECT_EQ(reader.frames().size(), 80u);
  EXPECT_GT(reader.margCount(), 10u);
  // Every marginalization of the gauge-free VO prior keeps |σ_min| tiny relative to σ_max.
  for (const MargRecord& marg : reader.margs(false)) {
    EXPECT_LT(std::abs(marg.sigma_min), 1e-3 * marg.sigma_max) << marg.frame_index;
  }

  const std::string python = test::findPythonWithH5py();
  if (python.empty()) {
    GTEST_SKIP() << "h5py not found (tried /usr/bin/python3 and python3): schema check skipped";
  }
  const auto check = test::runShell(python + " '" + sourceDir() +
                                    "/tools/scripts/check_results.py' '" + out + "'");
  EXPECT_EQ(check.exit_code, 0) << check.output;
  EXPECT_NE(check.output.find("OK"), std::string::npos) << check.output;
}

// VIO on EuRoC (the default mode there): body trajectory, 15-dof states, the same schema.
TEST_F(RunCliTest, VioRunOnEurocFollowsTheSchema) {
  const std::string out = path("mh01.h5");
  const auto result = runCli(
      "run --dataset euroc/MH_01_easy --variant ns-qr-sqrt-f32 --frames 60 -o '" + out + "'");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("VIO"), std::string::npos) << result.output;
  const ResultsReader reader(out);
  EXPECT_EQ(reader.info().status, "ok");
  EXPECT_EQ(reader.info().metadata.mode, "vio");
  EXPECT_EQ(reader.frames().size(), 60u);
  EXPECT_LT(reader.summary().ate_rmse, 0.05);
  const std::vector<MargRecord> margs = reader.margs(false);
  ASSERT_GT(margs.size(), 20u);
  // The gauge-free VIO prior: x, y, z, yaw stay flat, roll and pitch do not (gravity).
  const MargRecord& last = margs.back();
  EXPECT_LT(std::abs(last.dEm[0]), 1e-6 * std::abs(last.dEm[3]));
  EXPECT_LT(std::abs(last.dEm[5]), 1e-6 * std::abs(last.dEm[4]));

  const std::string python = test::findPythonWithH5py();
  if (python.empty()) GTEST_SKIP() << "h5py not found: schema check skipped";
  const auto check = test::runShell(python + " '" + sourceDir() +
                                    "/tools/scripts/check_results.py' '" + out + "'");
  EXPECT_EQ(check.exit_code, 0) << check.output;
}

// Same build, ISA and seed → the same estimates bit for bit, whatever the heap's layout. Before
// the ISA copies' calloc calls went to the 64-byte-aligned allocator (core/linalg/isa.h), a
// Schur-complement VIO run on AVX changed from frame 22 on when glibc placed blocks elsewhere
// (here: every block ≥ 4 KiB mapped on its own).
TEST_F(RunCliTest, SchurRunDoesNotDependOnTheHeapLayout) {
  for (const Isa isa : kAllIsas) {
    if (!isaAvailable(isa)) continue;
    SCOPED_TRACE(isaName(isa));
    const std::string args =
        std::string("run --dataset euroc/MH_02_easy --variant sc-qr-sqrt-f64 ") +
        "--frames 60 --no-diagnostics --isa " + isaName(isa) + " -o ";
    const std::string plain = path(std::string("plain_") + isaName(isa) + ".h5");
    const std::string moved = path(std::string("moved_") + isaName(isa) + ".h5");
    ASSERT_EQ(runCli(args + "'" + plain + "'").exit_code, 0);
    ASSERT_EQ(test::runShell("GLIBC_TUNABLES=glibc.malloc.mmap_threshold=4096 '" +
                             std::string(test::cliPath()) + "' " + args + "'" + moved + "'")
                  .exit_code,
              0);
    const FrameColumns a = ResultsReader(plain).frames(), b = ResultsReader(moved).frames();
    ASSERT_EQ(a.size(), 60u);
    ASSERT_EQ(b.size(), a.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      ASSERT_TRUE(a.p_est[i] == b.p_est[i] && a.q_est[i].coeffs() == b.q_est[i].coeffs() &&
                  a.cost_final[i] == b.cost_final[i])
          << "frame " << i;
    }
  }
}

TEST_F(RunCliTest, VioWithTheRealImuRecording) {
  const std::string out = path("v101.h5");
  const auto result =
      runCli("run --dataset euroc/V1_01_easy --variant ns-qr-sqrt-f32 --imu real --frames 60 -o '" +
             out + "'");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const ResultsReader reader(out);
  EXPECT_EQ(reader.info().status, "ok");
  EXPECT_LT(reader.summary().ate_rmse, 0.05);
  const auto& extra = reader.info().metadata.extra;
  const auto imu =
      std::find_if(extra.begin(), extra.end(), [](const auto& kv) { return kv.first == "imu"; });
  ASSERT_NE(imu, extra.end());
  EXPECT_NE(imu->second.find("real"), std::string::npos) << imu->second;

  // No recording, no IMU on KITTI, --imu real without VIO: clear errors, no file.
  const std::string none = path("none.h5");
  const auto no_imu = runCli(
      "run --dataset euroc/MH_01_easy --variant ns-qr-sqrt-f32 --imu real -o '" + none + "'");
  EXPECT_EQ(no_imu.exit_code, 1) << no_imu.output;
  EXPECT_NE(no_imu.output.find("no real IMU"), std::string::npos) << no_imu.output;
  const auto kitti_vio =
      runCli("run --dataset kitti/10 --variant ns-qr-sqrt-f32 --mode vio -o '" + none + "'");
  EXPECT_EQ(kitti_vio.exit_code, 1) << kitti_vio.output;
  EXPECT_NE(kitti_vio.output.find("no IMU"), std::string::npos) << kitti_vio.output;
  const auto vo_real =
      runCli("run --dataset euroc/V1_01_easy --variant ns-qr-sqrt-f32 --mode vo --imu real -o '" +
             none + "'");
  EXPECT_EQ(vo_real.exit_code, 2) << vo_real.output;
  EXPECT_FALSE(fs::exists(none));
}

TEST_F(RunCliTest, EigdumpPrintsThePriorsEigenvalues) {
  const std::string out = path("k10.h5");
  ASSERT_EQ(runCli("run --dataset kitti/10 --variant ns-qr-sqrt-f64 --frames 40 "
                   "--store-prior-every 10 -o '" +
                   out + "'")
                .exit_code,
            0);
  const auto dump = runCli("eigdump '" + out + "' --marg 10");
  EXPECT_EQ(dump.exit_code, 0) << dump.output;
  const auto csv = runCli("eigdump '" + out + "' --marg 10 --csv");
  EXPECT_EQ(csv.exit_code, 0) << csv.output;
  const ResultsReader reader(out);
  EXPECT_EQ(std::count(csv.output.begin(), csv.output.end(), '\n'),
            static_cast<long>(reader.eigenvalues(10).size()) + 1)
      << csv.output;
  const auto matrix = runCli("eigdump '" + out + "' --marg 10 --matrix");
  EXPECT_EQ(matrix.exit_code, 0) << matrix.output;
  EXPECT_NE(matrix.output.find("J_m"), std::string::npos) << matrix.output;
  EXPECT_NE(runCli("eigdump '" + out + "' --marg 100000").exit_code, 0);
}

TEST_F(RunCliTest, NanMeasurementEndsTheRunAsFailedWithACompleteFile) {
  const std::string out = path("nan.h5");
  const auto result = runCli(
      "run --dataset kitti/10 --variant sc-sc-sq-f64 --frames 40 "
      "--inject-nan-frame 20 -o '" +
      out + "'");
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find("FAILED at frame 20"), std::string::npos) << result.output;
  const ResultsReader reader(out);
  EXPECT_EQ(reader.info().status, "failed");
  EXPECT_EQ(reader.info().failure_frame, 20);
  EXPECT_NE(reader.info().failure_reason.find("not finite"), std::string::npos)
      << reader.info().failure_reason;
  EXPECT_EQ(reader.frames().size(), 21u);
}

TEST_F(RunCliTest, UsageErrorsExitWithTwoAndWriteNothing) {
  const std::string out = path("none.h5");
  for (const std::string& args :
       {"run --dataset kitti/10 --variant ns-qr-sqrt-f16 -o '" + out + "'",
        "run --dataset kitti/10 --variant ns-qr-sq-f32 -o '" + out + "'",
        "run --dataset kitti/10 --variant ns-qr-sqrt-f32 --no-such-option -o '" + out + "'"}) {
    const auto result = runCli(args);
    EXPECT_EQ(result.exit_code, 2) << args << "\n" << result.output;
  }
  EXPECT_FALSE(fs::exists(out));
  // An unknown dataset is a missing input: exit 1.
  EXPECT_EQ(runCli("run --dataset kitti/99 --variant ns-qr-sqrt-f32 -o '" + out + "'").exit_code,
            1);
  EXPECT_FALSE(fs::exists(out));
  const auto no_gt =
      runCli("run --dataset tumvi/slides1 --variant ns-qr-sqrt-f32 -o '" + out + "'");
  EXPECT_EQ(no_gt.exit_code, 1) << no_gt.output;
  EXPECT_NE(no_gt.output.find("no trajectory"), std::string::npos) << no_gt.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(RunCliTest, BadConfigNamesFileAndLine) {
  const std::string config = path("bad.toml");
  {
    std::ofstream file(config);
    file << "[lm]\nmax_iterations = 5\nlambda_init = \"big\"\n";
  }
  const auto result = runCli("run --dataset kitti/10 --variant ns-qr-sqrt-f32 --config '" + config +
                             "' -o '" + path("x.h5") + "'");
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find(config + ":3:"), std::string::npos) << result.output;
}

}  // namespace
}  // namespace marglab
