// Whole sequences: the shipped data against the numbers of datasets/README.md (from the MANIFEST of
// the originals), name resolution, user folders in the original layouts, and checkSequence.

#include <gtest/gtest.h>

#include <fmt/core.h>
#include <cstdlib>

#include "core/common/source_dir.h"
#include "core/data/parsers.h"
#include "core/data/sequence.h"
#include "data_test_utils.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::expectInputError;
using test::TempDir;
using test::writeFile;

const fs::path kShipped = fs::path(sourceDir()) / "datasets";

TEST(ShippedData, EurocWithAslGroundTruthAndImu) {
  const Sequence seq = loadSequence("euroc/MH_04_difficult");
  EXPECT_EQ(seq.kind, DatasetKind::kEuroc);
  EXPECT_EQ(seq.name, "euroc/MH_04_difficult");
  EXPECT_EQ(seq.gt_source, "ASL csv");
  EXPECT_FALSE(seq.gt_is_estimate);
  ASSERT_EQ(seq.gt.size(), 19753u);
  EXPECT_EQ(seq.gt.t_ns.front(), 1403638128940097024);
  EXPECT_EQ(seq.gt.t_ns.back(), 1403638227700097024);
  ASSERT_TRUE(seq.gt_imu_state.has_value());
  EXPECT_EQ(seq.gt_imu_state->bias_accel.size(), 19753u);
  EXPECT_EQ(seq.gt_imu_state->bias_gyro[0], Eigen::Vector3d(-0.002133, 0.021059, 0.076659));
  ASSERT_EQ(seq.cam_t_ns.size(), 2033u);
  EXPECT_EQ(seq.cam_t_ns.front(), 1403638127245096960);
  ASSERT_TRUE(seq.imu.has_value());
  EXPECT_EQ(seq.imu->size(), 20320u);
  EXPECT_EQ(seq.imu->t_ns.front(), 1403638127270096896);
  EXPECT_EQ(seq.calib.cam0.fx, 458.654);
  EXPECT_EQ(seq.calib.cam1.fx, 457.587);
  EXPECT_EQ(seq.calib.cam0.t_b_c,
            Eigen::Vector3d(-0.0216401454975, -0.064676986768, 0.00981073058949));
  EXPECT_NEAR(seq.calib.baseline(), 0.110, 1e-3);
  EXPECT_EQ(seq.imu_noise.gyro_noise_density, 1.6968e-4);
  EXPECT_EQ(seq.imu_noise.accel_random_walk, 3.0e-3);
  EXPECT_EQ(seq.defaults.grid_cell_px, 50.0);
  EXPECT_EQ(seq.defaults.max_position_error_m, 5.0);
  EXPECT_EQ(seq.defaults.min_frames_after_kf, 5);

  const SequenceCheck check = checkSequence(seq);
  EXPECT_FALSE(check.timestamps_only);
  EXPECT_NEAR(check.imu_rate_hz, 200.0, 0.01);
  EXPECT_GT(check.frames_in_gt, 1900u);
  EXPECT_LT(check.frames_in_gt, 2033u);
}

TEST(ShippedData, EurocTumOnlyWithoutImu) {
  const Sequence seq = loadSequence("euroc/MH_01_easy");
  EXPECT_EQ(seq.gt_source, "TUM txt");
  EXPECT_EQ(seq.gt.size(), 36382u);
  EXPECT_EQ(seq.gt.t_ns.front(), 1403636580838560000);  // TUM times are rounded to 10 µs
  EXPECT_FALSE(seq.gt_imu_state.has_value());
  EXPECT_FALSE(seq.imu.has_value());
  EXPECT_TRUE(seq.imu_file.empty());
  EXPECT_EQ(seq.cam_t_ns.size(), 3682u);
  EXPECT_EQ(seq.cam_t_ns.front(), 1403636579763555584);
  EXPECT_EQ(loadSequence("euroc/V2_03_difficult").cam_t_ns.size(), 1922u);  // dropped frames
}

TEST(ShippedData, TumviRoomAliasAndCalibration) {
  const Sequence seq = loadSequence("tumvi/dataset-room1_512_16");
  EXPECT_EQ(seq.name, "tumvi/room1");
  EXPECT_EQ(seq.kind, DatasetKind::kTumvi);
  EXPECT_EQ(seq.gt.size(), 16541u);
  EXPECT_EQ(seq.gt.t_ns.front(), 1520530308189679351);
  EXPECT_FALSE(seq.gt_imu_state.has_value());
  ASSERT_TRUE(seq.imu.has_value());
  EXPECT_EQ(seq.imu->size(), 28122u);
  EXPECT_EQ(seq.cam_t_ns.size(), 2821u);
  EXPECT_EQ(seq.calib.cam0.fx, 190.97847715128717);
  EXPECT_EQ(seq.calib.cam0.width, 512);
  EXPECT_EQ(seq.calib.cam0.distortion_model, "equidistant");
  // T_b_c is the inverse of the file's T_cam_imu: R_c_b · (row 0 of R_c_b)ᵀ = e_x, R_c_b = R_b_cᵀ.
  const Eigen::Vector3d row0(-0.9995250378696743, 0.029615343885863205, -0.008522328211654736);
  EXPECT_NEAR((seq.calib.cam0.R_b_c.transpose() * row0 - Eigen::Vector3d::UnitX()).norm(), 0, 1e-9);
  EXPECT_NEAR(seq.calib.baseline(), 0.101, 1e-3);
  EXPECT_EQ(seq.imu_noise.gyro_noise_density, 1.6e-4);
  EXPECT_EQ(seq.imu_noise.accel_random_walk, 8.6e-4);
  const SequenceCheck check = checkSequence(seq);
  EXPECT_NEAR(check.imu_rate_hz, 200.0, 1.0);
  EXPECT_GT(check.max_gt_gap_s, 1.0);  // mocap gaps are real
}

TEST(ShippedData, TumviEstimateAndTimestampsOnly) {
  const Sequence corridor1 = loadSequence("tumvi/corridor1");
  EXPECT_TRUE(corridor1.gt_is_estimate);
  EXPECT_EQ(corridor1.gt_source, "OKVIS estimate");
  EXPECT_EQ(corridor1.gt.size(), 5986u);
  EXPECT_EQ(loadSequence("tumvi/magistrale1").gt.size(), 3759u);

  const Sequence corridor2 = loadSequence("tumvi/corridor2");
  EXPECT_FALSE(corridor2.hasTrajectory());
  EXPECT_EQ(corridor2.cam_t_ns.size(), 6772u);
  const SequenceCheck check = checkSequence(corridor2);
  EXPECT_TRUE(check.timestamps_only);
  EXPECT_EQ(check.frames, 6772u);
}

TEST(ShippedData, KittiPosesTimesCalib) {
  const Sequence seq = loadSequence("kitti/00");
  EXPECT_EQ(seq.kind, DatasetKind::kKitti);
  ASSERT_EQ(seq.gt.size(), 4541u);
  EXPECT_EQ(seq.cam_t_ns, seq.gt.t_ns);
  EXPECT_EQ(seq.gt.t_ns.back(), 470581600000);
  EXPECT_LT(seq.gt.p_w_b.front().norm(), 1e-12);  // world = cam0 at frame 0
  EXPECT_NEAR(seq.gt.p_w_b.back().z(), 96.961530, 1e-6);
  EXPECT_NEAR(seq.calib.baseline(), 0.5372, 1e-4);
  EXPECT_EQ(seq.calib.cam0.fx, 718.856);
  EXPECT_EQ(seq.defaults.grid_cell_px, 30.0);
  EXPECT_EQ(seq.defaults.max_position_error_m, 100.0);
  EXPECT_EQ(seq.defaults.min_frames_after_kf, 1);
  EXPECT_EQ(loadSequence("kitti/03").calib.cam0.fx, 721.5377);
  const Sequence s04 = loadSequence("kitti/04");
  EXPECT_EQ(s04.calib.cam0.fx, 707.0912);
  EXPECT_EQ(s04.calib.cam0.cx, 601.8873);
  EXPECT_EQ(s04.gt.size(), 271u);
}

TEST(ShippedData, ListAndUnknownName) {
  const std::vector<std::string> names = listSequences();
  // 30 with ground truth or timestamps + the image folders euroc/V1_01_easy_images,
  // euroc/V1_01_easy_keyframes, kitti/06_images
  EXPECT_EQ(names.size(), 33u);
  EXPECT_EQ(names.front(), "euroc/MH_01_easy");
  EXPECT_EQ(names.back(), "kitti/10");
  expectInputError([] { loadSequence("euroc/MH_06_impossible"); }, "euroc/MH_06_impossible", 0,
                   "euroc/MH_01_easy, euroc/MH_02_easy");
}

TEST(ShippedData, LoadWithoutImuKeepsItsFile) {
  const Sequence seq = loadSequence("euroc/V1_02_medium", LoadOptions{false});
  EXPECT_FALSE(seq.imu.has_value());
  EXPECT_FALSE(seq.imu_file.empty());
}

TEST(DatasetsRoot, EnvironmentVariableOverrides) {
  TempDir dir;
  fs::create_directories(dir.path() / "kitti");
  fs::copy(kShipped / "kitti" / "04", dir.path() / "kitti" / "04");
  ASSERT_EQ(setenv("MARGLAB_DATASETS", dir.path().c_str(), 1), 0);
  const std::vector<std::string> names = listSequences();
  const std::string root = datasetsRoot();
  const Sequence seq = loadSequence("kitti/04");
  unsetenv("MARGLAB_DATASETS");
  EXPECT_EQ(root, dir.path().string());
  EXPECT_EQ(names, std::vector<std::string>{"kitti/04"});
  EXPECT_EQ(seq.gt.size(), 271u);
  EXPECT_EQ(datasetsRoot(), kShipped.string());
}

// A small synthetic sequence in the original EuRoC / TUM-VI ASL layout.
void writeAslFolder(const fs::path& mav, bool tumvi, int imu_period_ns) {
  const int64_t t0 = 1403636580000000000;
  std::string gt = "#timestamp, p, q\n";
  for (int i = 0; i <= 200; ++i) {
    const int64_t t = t0 + i * 5000000LL;
    gt += tumvi ? fmt::format("{},{},0,1,1,0,0,0\n", t, 0.01 * i)
                : fmt::format("{},{},0,1,1,0,0,0,0.5,0,0,0.001,0.002,0.003,0.1,0.2,0.3\n", t,
                              0.01 * i);
  }
  writeFile((mav / (tumvi ? "mocap0" : "state_groundtruth_estimate0") / "data.csv").string(), gt);
  std::string imu = "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\r\n";
  for (int64_t t = t0 - 100000000; t <= t0 + 1100000000; t += imu_period_ns) {
    imu += fmt::format("{},0,0,0,0,0,9.81\r\n", t);
  }
  writeFile((mav / "imu0" / "data.csv").string(), imu);
  std::string cam = "#timestamp [ns],filename\n";
  for (int i = -2; i <= 21; ++i) cam += fmt::format("{},{}.png\n", t0 + i * 50000000LL, i);
  writeFile((mav / "cam0" / "data.csv").string(), cam);
  if (!tumvi) {
    for (const char* c : {"cam0", "cam1"}) {
      fs::create_directories(mav / c);
      fs::copy_file(kShipped / "euroc" / "calib" / (std::string(c) + "_sensor.yaml"),
                    mav / c / "sensor.yaml");
    }
  }
}

TEST(UserFolder, EurocAslLayout) {
  TempDir dir;
  writeAslFolder(dir.path() / "mav0", false, 5000000);
  const Sequence seq = loadSequence(dir.path().string());
  EXPECT_EQ(seq.kind, DatasetKind::kEuroc);
  EXPECT_EQ(seq.gt.size(), 201u);
  ASSERT_TRUE(seq.gt_imu_state.has_value());
  EXPECT_EQ(seq.gt_imu_state->v_w_b[3], Eigen::Vector3d(0.5, 0, 0));
  EXPECT_EQ(seq.cam_t_ns.size(), 24u);
  EXPECT_EQ(seq.imu->size(), 241u);
  EXPECT_EQ(seq.calib.cam1.fx, 457.587);
  const SequenceCheck check = checkSequence(seq);
  EXPECT_EQ(check.frames_in_gt, 21u);
  EXPECT_NEAR(check.imu_rate_hz, 200.0, 1e-9);
  // The mav0 folder itself works too.
  EXPECT_EQ(loadSequence((dir.path() / "mav0").string()).gt.size(), 201u);
}

TEST(UserFolder, TumviAslLayoutFallsBackToShippedCalibration) {
  TempDir dir;
  writeAslFolder(dir.path() / "mav0", true, 5000000);
  const Sequence seq = loadSequence(dir.path().string());
  EXPECT_EQ(seq.kind, DatasetKind::kTumvi);
  EXPECT_FALSE(seq.gt_imu_state.has_value());
  EXPECT_EQ(seq.calib.cam0.width, 512);
  EXPECT_NE(seq.calib_source.find("tumvi/calib"), std::string::npos);
}

// A TUM-VI folder's own imu0/sensor.yaml (as `marglab datasets render` writes) sets the noise.
TEST(UserFolder, TumviImuNoiseFromItsImuSensorYaml) {
  TempDir dir;
  writeAslFolder(dir.path() / "mav0", true, 5000000);
  writeFile((dir.path() / "mav0/imu0/sensor.yaml").string(),
            "sensor_type: imu\ngyroscope_noise_density: 0.001\ngyroscope_random_walk: 0.002\n"
            "accelerometer_noise_density: 0.003\naccelerometer_random_walk: 0.004\n");
  const Sequence seq = loadSequence(dir.path().string());
  EXPECT_EQ(seq.imu_noise.gyro_noise_density, 0.001);
  EXPECT_EQ(seq.imu_noise.gyro_random_walk, 0.002);
  EXPECT_EQ(seq.imu_noise.accel_noise_density, 0.003);
  EXPECT_EQ(seq.imu_noise.accel_random_walk, 0.004);
}

TEST(UserFolder, CheckRejectsWrongImuRateAndDisjointGt) {
  TempDir dir;
  writeAslFolder(dir.path() / "mav0", false, 10000000);
  const Sequence seq = loadSequence(dir.path().string());
  expectInputError([&] { checkSequence(seq); }, seq.imu_file, 0,
                   "expected an IMU rate of 200 Hz ± 10 %, found 100.0 Hz");

  Sequence shifted = seq;
  for (auto& t : shifted.gt.t_ns) t += 3600LL * 1000000000LL;
  expectInputError([&] { checkSequence(shifted); }, seq.gt_file, 0, "expected the trajectory");
}

TEST(UserFolder, KittiOfficialLayoutAndShippedLayoutCopy) {
  TempDir dir;
  const fs::path seq_dir = dir.path() / "dataset" / "sequences" / "04";
  fs::create_directories(seq_dir);
  fs::create_directories(dir.path() / "dataset" / "poses");
  fs::copy_file(kShipped / "kitti/04/calib.txt", seq_dir / "calib.txt");
  fs::copy_file(kShipped / "kitti/04/times.txt.gz", seq_dir / "times.txt.gz");
  writeFile((dir.path() / "dataset/poses/04.txt").string(),
            test::readGz((kShipped / "kitti/04/poses.txt.gz").string()));
  const Sequence kitti = loadSequence(seq_dir.string());
  EXPECT_EQ(kitti.name, "kitti/04");
  EXPECT_EQ(kitti.gt.size(), 271u);
  // The download's root with one sequence stands for it; with two it is ambiguous.
  const Sequence root = loadSequence((dir.path() / "dataset").string());
  EXPECT_EQ(root.directory, seq_dir.string());
  EXPECT_EQ(root.gt.size(), 271u);
  EXPECT_EQ(sequenceKind((dir.path() / "dataset").string()), DatasetKind::kKitti);
  fs::create_directories(dir.path() / "dataset/sequences/05");
  fs::copy_file(kShipped / "kitti/05/times.txt.gz",
                dir.path() / "dataset/sequences/05/times.txt.gz");
  expectInputError([&] { loadSequence((dir.path() / "dataset").string()); },
                   (dir.path() / "dataset/sequences").string(), 0,
                   "expected exactly one sequence folder with times.txt, found 2 (04, 05)");

  fs::create_directories(dir.path() / "euroc");
  fs::copy(kShipped / "euroc/calib", dir.path() / "euroc/calib");
  fs::copy(kShipped / "euroc/V1_02_medium", dir.path() / "euroc/V1_02_medium");
  const Sequence euroc = loadSequence((dir.path() / "euroc/V1_02_medium").string());
  EXPECT_EQ(euroc.name, "euroc/V1_02_medium");
  EXPECT_EQ(euroc.gt.size(), 16702u);

  fs::create_directories(dir.path() / "elsewhere");
  fs::copy(kShipped / "euroc/V1_02_medium", dir.path() / "elsewhere/V1_02_medium");
  expectInputError([&] { loadSequence((dir.path() / "elsewhere/V1_02_medium").string()); },
                   (dir.path() / "elsewhere/V1_02_medium").string(), 0,
                   "inside a folder named euroc or tumvi");
  expectInputError([&] { loadSequence(dir.path().string()); }, dir.path().string(), 0,
                   "expected a sequence folder");
}

}  // namespace
}  // namespace marglab
