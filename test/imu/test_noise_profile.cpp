// IMU noise profiles (issue #19): the Basalt densities read from the shipped calibration files,
// the profile reaching both the synthetic IMU and the estimator's weights, and the config key.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include "common/cli_runner.h"
#include "core/common/error.h"
#include "core/data/parsers.h"
#include "core/data/sequence.h"
#include "core/estimator/window_io.h"
#include "core/imu/noise_profile.h"
#include "core/io/results_file.h"
#include "core/pipeline/run.h"
#include "core/sim/trajectory_spline.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;

// Basalt's data/euroc_ds_calib.json and data/tumvi_512_ds_calib.json (and the EUCM files): the same
// four densities for both datasets.
ImuNoise basaltDensities() {
  ImuNoise n;
  n.gyro_noise_density = 0.000282;
  n.gyro_random_walk = 0.0001;
  n.accel_noise_density = 0.016;
  n.accel_random_walk = 0.001;
  return n;
}

void expectNoise(const ImuNoise& actual, const ImuNoise& expected) {
  EXPECT_EQ(actual.gyro_noise_density, expected.gyro_noise_density);
  EXPECT_EQ(actual.gyro_random_walk, expected.gyro_random_walk);
  EXPECT_EQ(actual.accel_noise_density, expected.accel_noise_density);
  EXPECT_EQ(actual.accel_random_walk, expected.accel_random_walk);
}

std::string calibFile(const std::string& name) {
  return (fs::path(datasetsRoot()) / name).string();
}

TEST(NoiseProfile, ShippedBasaltCalibrationsHoldBasaltsDensities) {
  for (const char* name :
       {"euroc/calib/basalt_euroc_ds_calib.json", "euroc/calib/basalt_euroc_eucm_calib.json",
        "tumvi/calib/basalt_tumvi_512_ds_calib.json",
        "tumvi/calib/basalt_tumvi_512_eucm_calib.json"}) {
    SCOPED_TRACE(name);
    expectNoise(readBasaltImuNoise(calibFile(name)), basaltDensities());
  }
  EXPECT_EQ(basaltCalibrationFile(DatasetKind::kEuroc),
            calibFile("euroc/calib/basalt_euroc_ds_calib.json"));
  EXPECT_EQ(basaltCalibrationFile(DatasetKind::kTumvi),
            calibFile("tumvi/calib/basalt_tumvi_512_ds_calib.json"));
  EXPECT_THROW(basaltCalibrationFile(DatasetKind::kKitti), InputError);
}

TEST(NoiseProfile, NamesRoundTripAndUnknownIsRejected) {
  for (ImuNoiseProfile p : {ImuNoiseProfile::kKalibr, ImuNoiseProfile::kBasalt}) {
    ImuNoiseProfile parsed =
        p == ImuNoiseProfile::kKalibr ? ImuNoiseProfile::kBasalt : ImuNoiseProfile::kKalibr;
    ASSERT_TRUE(parseImuNoiseProfile(toString(p), &parsed));
    EXPECT_EQ(parsed, p);
  }
  ImuNoiseProfile p = ImuNoiseProfile::kKalibr;
  EXPECT_FALSE(parseImuNoiseProfile("Basalt", &p));
  EXPECT_FALSE(parseImuNoiseProfile("", &p));
  EXPECT_EQ(p, ImuNoiseProfile::kKalibr);
}

TEST(NoiseProfile, KalibrIsTheSequencesOwnAndBasaltTheShippedJson) {
  for (const char* name : {"euroc/MH_01_easy", "tumvi/room1"}) {
    SCOPED_TRACE(name);
    const Sequence seq = loadSequence(name, LoadOptions{false});
    const std::string kind = datasetKindName(seq.kind);
    expectNoise(profileImuNoise(seq, ImuNoiseProfile::kKalibr),
                readKalibrImuNoise(calibFile(kind + "/calib/openvins_kalibr_imu_chain.yaml")));
    expectNoise(profileImuNoise(seq, ImuNoiseProfile::kBasalt), basaltDensities());
  }
  const Sequence kitti = loadSequence("kitti/00", LoadOptions{false});
  EXPECT_THROW(profileImuNoise(kitti, ImuNoiseProfile::kBasalt), InputError);
}

// A Basalt-like file with `body` between the braces; its path.
std::string writeJson(const std::string& name, const std::string& body) {
  const fs::path dir =
      fs::temp_directory_path() / ("marglab_test_noise_profile_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path path = dir / name;
  std::ofstream(path) << "{\n  \"value0\": {\n" << body << "\n  }\n}\n";
  return path.string();
}

void expectInputError(const std::string& path, int line, const std::string& fragment) {
  try {
    readBasaltImuNoise(path);
    ADD_FAILURE() << "no error for " << path;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    if (line > 0) {
      EXPECT_NE(what.find(":" + std::to_string(line)), std::string::npos) << what;
    }
    EXPECT_NE(what.find(fragment), std::string::npos) << what;
  }
}

TEST(NoiseProfile, MalformedBasaltFilesNameTheFileLineAndKey) {
  const std::string good_rest =
      "    \"gyro_noise_std\": [0.1, 0.1, 0.1],\n    \"accel_bias_std\": [1, 1, 1],\n"
      "    \"gyro_bias_std\": [2, 2, 2]";
  // Line 3: the first line of the body.
  expectInputError(writeJson("missing.json", good_rest), 0, "\"accel_noise_std\"");
  expectInputError(
      writeJson("anisotropic.json", "    \"accel_noise_std\": [0.1, 0.2, 0.1],\n" + good_rest), 3,
      "three equal values");
  expectInputError(writeJson("two.json", "    \"accel_noise_std\": [0.1, 0.1],\n" + good_rest), 3,
                   "three equal values");
  expectInputError(writeJson("zero.json", "    \"accel_noise_std\": [0, 0, 0],\n" + good_rest), 3,
                   "three equal values");
  expectInputError(writeJson("text.json", "    \"accel_noise_std\": [0.1, x, 0.1],\n" + good_rest),
                   3, "expected a number");
  expectInputError(writeJson("scalar.json", "    \"accel_noise_std\": 0.1,\n" + good_rest), 3,
                   "[x, y, z]");
  expectInputError(writeJson("twice.json", "    \"accel_noise_std\": [1, 1, 1],\n" + good_rest +
                                               ",\n    \"accel_noise_std\": [1, 1, 1]"),
                   7, "once");
  // Multi-line lists as Basalt's cereal output writes them.
  const ImuNoise n = readBasaltImuNoise(writeJson(
      "multiline.json",
      "    \"accel_noise_std\": [\n      0.5,\n      0.5,\n      0.5\n    ],\n" + good_rest));
  EXPECT_EQ(n.accel_noise_density, 0.5);
  EXPECT_EQ(n.gyro_noise_density, 0.1);
  EXPECT_EQ(n.accel_random_walk, 1.0);
  EXPECT_EQ(n.gyro_random_walk, 2.0);
}

// vioImuSetup: the profile's densities are the estimator's (ImuSetup::noise) and the synthetic
// IMU's. The first synthetic sample carries zero bias, so its error is the white noise alone,
// σ/√Δt times the same N(0,1) draws for every profile (same seed): the ratio of the errors of two
// profiles is the ratio of their densities.
TEST(NoiseProfile, VioImuSetupSynthesizesAndWeighsWithTheProfile) {
  const Sequence seq = loadSequence("euroc/V1_01_easy", LoadOptions{false});
  const TrajectorySpline spline = TrajectorySpline::fromSequence(seq);
  std::map<ImuNoiseProfile, ImuSetup> setups;
  for (ImuNoiseProfile p : {ImuNoiseProfile::kKalibr, ImuNoiseProfile::kBasalt}) {
    RunSpec options;
    options.seed = 3;
    options.config.estimator.imu_noise_profile = p;
    std::map<std::string, std::string> provenance;
    setups[p] = vioImuSetup(options, seq, spline, spline.startTimeNs(), &provenance);
    EXPECT_NE(provenance["imu_noise"].find(toString(p)), std::string::npos);
  }
  const ImuSetup& kalibr = setups[ImuNoiseProfile::kKalibr];
  const ImuSetup& basalt = setups[ImuNoiseProfile::kBasalt];
  expectNoise(kalibr.noise, seq.imu_noise);
  expectNoise(basalt.noise, basaltDensities());
  ASSERT_FALSE(basalt.imu.t_ns.empty());
  ASSERT_EQ(basalt.imu.t_ns.front(), kalibr.imu.t_ns.front());
  const TrajectorySample truth = spline.evaluate(basalt.imu.t_ns.front());
  const Eigen::Vector3d f_true = truth.R_w_b.transpose() * (truth.a_w - basalt.g_w);
  const Eigen::Vector3d e_g_basalt = basalt.imu.gyro.front() - truth.omega_b;
  const Eigen::Vector3d e_g_kalibr = kalibr.imu.gyro.front() - truth.omega_b;
  const Eigen::Vector3d e_a_basalt = basalt.imu.accel.front() - f_true;
  const Eigen::Vector3d e_a_kalibr = kalibr.imu.accel.front() - f_true;
  const double gyro_ratio = basaltDensities().gyro_noise_density / seq.imu_noise.gyro_noise_density;
  const double accel_ratio =
      basaltDensities().accel_noise_density / seq.imu_noise.accel_noise_density;
  // The errors (≈ 4e-3 rad/s, 0.03 m/s²) are differences of values ≲ 10: a few ulps of 10 over
  // the error size bound the relative error of each ratio.
  const double tol = 1e-10;
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(e_g_basalt[i] / e_g_kalibr[i], gyro_ratio, tol * gyro_ratio) << i;
    EXPECT_NEAR(e_a_basalt[i] / e_a_kalibr[i], accel_ratio, tol * accel_ratio) << i;
  }
}

// Through the CLI: the config key reaches the results file and the estimator's window (whose
// ImuNoise weighs the preintegration and bias factors), and a bad value is an input error.
TEST(NoiseProfile, ConfigKeyReachesTheEstimatorAndBadValuesExit1) {
  const fs::path dir =
      fs::temp_directory_path() / ("marglab_test_noise_profile_cli_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "basalt.toml") << "[imu]\nnoise_profile = \"basalt\"\n";
  const test::CliResult r = test::runCli(
      "run --dataset euroc/V1_01_easy --variant ns-qr-sqrt-f64 --frames 12 --no-diagnostics "
      "--config '" +
      (dir / "basalt.toml").string() + "' --dump-windows 10 --dump-dir '" + (dir / "w").string() +
      "' -o '" + (dir / "r.h5").string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const WindowSnapshot w =
      readWindow((dir / "w" / "euroc-V1_01_easy_ns-qr-sqrt-f64_000010.win.gz").string());
  expectNoise(w.imu_noise, basaltDensities());
  const ResultsReader results((dir / "r.h5").string());
  const std::string& config = results.info().metadata.config_toml;
  EXPECT_NE(config.find("[imu]\nnoise_profile = 'basalt'"), std::string::npos) << config;

  std::ofstream(dir / "bad.toml") << "# comment\n[imu]\nnoise_profile = \"okvis\"\n";
  const test::CliResult bad = test::runCli(
      "run --dataset euroc/V1_01_easy --variant ns-qr-sqrt-f64 --frames 12 --config '" +
      (dir / "bad.toml").string() + "' -o '" + (dir / "bad.h5").string() + "'");
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("bad.toml:3"), std::string::npos) << bad.output;
  EXPECT_NE(bad.output.find("imu.noise_profile"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(dir / "bad.h5"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace marglab
