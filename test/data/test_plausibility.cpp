// Plausibility limits (core/data/plausibility.h): implausible poses, IMU samples, static
// trajectories, stereo baselines and folders standing for files are refused at their line by the
// parsers and loaders (issue #18, items 2, 7, 9 and 11), and overlong tokens are cut in messages.

#include <gtest/gtest.h>

#include <fmt/core.h>

#include <algorithm>
#include <sstream>

#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/data/parsers.h"
#include "core/data/plausibility.h"
#include "core/data/sequence.h"
#include "data_test_utils.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::expectInputError;
using test::TempDir;
using test::writeFile;

const fs::path kShipped = fs::path(sourceDir()) / "datasets";

// KITTI 10 copied into dir/10 with line `line` of poses.txt (1-based) passed through `edit`.
template <typename Edit>
fs::path kittiCopy(const TempDir& dir, int line, Edit edit) {
  const fs::path seq = dir.path() / "10";
  fs::create_directories(seq);
  const auto overwrite = fs::copy_options::overwrite_existing;
  fs::copy_file(kShipped / "kitti/10/calib.txt", seq / "calib.txt", overwrite);
  fs::copy_file(kShipped / "kitti/10/times.txt.gz", seq / "times.txt.gz", overwrite);
  std::istringstream poses(test::readGz((kShipped / "kitti/10/poses.txt.gz").string()));
  std::string text, row;
  for (int n = 1; std::getline(poses, row); ++n) text += (n == line ? edit(row) : row) + "\n";
  writeFile((seq / "poses.txt").string(), text);
  return seq;
}

// The row with its 4th value (x translation) replaced.
std::string withX(const std::string& row, const std::string& x) {
  std::istringstream in(row);
  std::vector<std::string> v(12);
  for (auto& value : v) in >> value;
  v[3] = x;
  std::string out;
  for (const auto& value : v) out += (out.empty() ? "" : " ") + value;
  return out;
}

TEST(Plausibility, KittiPoseMovedFarIsRefusedAtItsLine) {
  TempDir dir;
  for (const char* x : {"1e5", "1e300"}) {
    const fs::path seq = kittiCopy(dir, 500, [&](const std::string& r) { return withX(r, x); });
    expectInputError([&] { loadSequence(seq.string()); }, (seq / "poses.txt").string(), 500,
                     "expected a step of at most 10 m from the previous pose (car), found");
  }
}

TEST(Plausibility, SpeedAndStepLimitsPerDatasetKind) {
  const PlausibilityLimits& car = plausibilityLimits(DatasetKind::kKitti);
  const PlausibilityLimits& mav = plausibilityLimits(DatasetKind::kEuroc);
  const Eigen::Vector3d p0 = Eigen::Vector3d::Zero();
  // 2 m in 0.1 s = 20 m/s: within both limits.
  EXPECT_EQ(poseStepProblem(car, 0, p0, 100000000, Eigen::Vector3d(2, 0, 0)), "");
  EXPECT_EQ(poseStepProblem(mav, 0, p0, 100000000, Eigen::Vector3d(2, 0, 0)), "");
  // 1 m in 5 ms = 200 m/s: over both speed limits, under the step limit.
  const std::string fast = poseStepProblem(mav, 0, p0, 5000000, Eigen::Vector3d(0, 1, 0));
  EXPECT_NE(fast.find("expected a speed of at most 50 m/s"), std::string::npos) << fast;
  EXPECT_NE(fast.find("= 200 m/s"), std::string::npos) << fast;
  // 7.5 m in 0.1 s = 75 m/s: over the car's 70 m/s.
  EXPECT_NE(poseStepProblem(car, 0, p0, 100000000, Eigen::Vector3d(7.5, 0, 0)), "");
  // A step over 10 m across a long gap is still refused; NaN is refused, not passed.
  EXPECT_NE(poseStepProblem(car, 0, p0, 10000000000, Eigen::Vector3d(11, 0, 0)), "");
  EXPECT_NE(poseStepProblem(car, 0, p0, 100000000, Eigen::Vector3d(NAN, 0, 0)), "");
}

TEST(Plausibility, TumTrajectoryJumpNamesLineValueAndLimit) {
  TempDir dir;
  const std::string path = writeFile(dir.file("gt.txt"),
                                     "1.000 0 0 0 0 0 0 1\n"
                                     "1.005 0.001 0 0 0 0 0 1\n"
                                     "1.010 1e5 0 0 0 0 0 1\n");
  EXPECT_EQ(readTumTrajectory(path).size(), 3u);  // without limits: a plain parse
  expectInputError([&] { readTumTrajectory(path, &plausibilityLimits(DatasetKind::kTumvi)); }, path,
                   3,
                   "expected a step of at most 10 m from the previous pose (MAV / handheld rig), "
                   "found 100000 m");
}

const char* const kImuHeader = "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n";

std::string imuRows(int64_t t0, int n, int64_t period) {
  std::string rows;
  for (int i = 0; i < n; ++i) rows += fmt::format("{},0.01,0,0,0,0,9.81\n", t0 + i * period);
  return rows;
}

TEST(Plausibility, ImuGapRangeAreRefusedAtTheirLine) {
  TempDir dir;
  const PlausibilityLimits* euroc = &plausibilityLimits(DatasetKind::kEuroc);
  const int64_t t0 = 1403715523912143104;
  const std::string good = writeFile(dir.file("good.csv"), kImuHeader + imuRows(t0, 20, 5000000));
  EXPECT_EQ(readAslImu(good, euroc).size(), 20u);

  // A 9.5 s gap after the 10th sample (line 11): line 12 is refused.
  const std::string gap =
      writeFile(dir.file("gap.csv"), kImuHeader + imuRows(t0, 10, 5000000) +
                                         imuRows(t0 + 9 * 5000000 + 9500000000, 10, 5000000));
  expectInputError([&] { readAslImu(gap, euroc); }, gap, 12,
                   fmt::format("expected IMU samples at most 0.05 s apart (nominal 200 Hz), found "
                               "a gap of 9.5 s after t = {} ns",
                               t0 + 9 * 5000000));
  const std::string huge =
      writeFile(dir.file("huge.csv"), kImuHeader + imuRows(t0, 3, 5000000) +
                                          fmt::format("{},0,0,0,1e30,0,9.81\n", t0 + 3 * 5000000));
  expectInputError([&] { readAslImu(huge, euroc); }, huge, 5,
                   "expected accelerations within ±176.5 m/s² (the accelerometer's range), found "
                   "1e+30");
  const std::string spin =
      writeFile(dir.file("spin.csv"), kImuHeader + imuRows(t0, 3, 5000000) +
                                          fmt::format("{},0,-20,0,0,0,9.81\n", t0 + 3 * 5000000));
  expectInputError([&] { readAslImu(spin, euroc); }, spin, 5,
                   "expected angular rates within ±17.5 rad/s (the gyroscope's range), found 20");
  // TUM-VI's BMI160 has twice the gyroscope range.
  EXPECT_EQ(readAslImu(spin, &plausibilityLimits(DatasetKind::kTumvi)).size(), 4u);
}

TEST(Plausibility, ShippedImuGapIsRefusedByTheLoader) {
  TempDir dir;
  fs::create_directories(dir.path() / "euroc");
  fs::copy(kShipped / "euroc/calib", dir.path() / "euroc/calib");
  const fs::path seq = dir.path() / "euroc/V1_02_medium";
  fs::create_directories(seq);
  for (const char* f : {"cam0_timestamps_ns.txt.gz", "gt_asl.csv.gz"}) {
    fs::copy_file(kShipped / "euroc/V1_02_medium" / f, seq / f);
  }
  std::istringstream imu(test::readGz((kShipped / "euroc/V1_02_medium/imu0_asl.csv.gz").string()));
  std::string text, row;
  for (int n = 1; std::getline(imu, row); ++n) {
    if (n <= 1001 || n > 2901) text += row + "\n";  // drop 1900 samples: a 9.5 s gap
  }
  writeFile((seq / "imu0_asl.csv").string(), text);
  expectInputError(
      [&] { loadSequence(seq.string()); }, (seq / "imu0_asl.csv").string(), 1002,
      "expected IMU samples at most 0.05 s apart (nominal 200 Hz), found a gap of 9.5");
}

// A static recording is valid data (issue #32): it loads, and check notes it; a zero baseline is
// physically impossible and refused.
TEST(Plausibility, StaticTrajectoryIsANoteAndZeroBaselineAnInputError) {
  TempDir dir;
  const fs::path seq = kittiCopy(dir, 0, [](const std::string& r) { return r; });
  std::string still;
  for (std::size_t i = 0; i < loadSequence(seq.string()).gt.size(); ++i) {
    still += "1 0 0 0 0 1 0 0 0 0 1 0\n";
  }
  writeFile((seq / "poses.txt").string(), still);
  const Sequence loaded = loadSequence(seq.string());
  EXPECT_NE(pathLengthNote(loaded).find("the trajectory moves 0 m"), std::string::npos)
      << pathLengthNote(loaded);
  const SequenceCheck check = checkSequence(loaded);
  EXPECT_NE(std::find(check.notes.begin(), check.notes.end(), pathLengthNote(loaded)),
            check.notes.end());

  fs::remove(seq / "poses.txt");
  const std::string calib = test::readGz((kShipped / "kitti/10/calib.txt").string());
  std::istringstream in(calib);
  std::string text, row;
  while (std::getline(in, row)) {
    if (row.rfind("P1:", 0) == 0) row = "P1: 707.0912 0 601.8873 0 0 707.0912 183.1104 0 0 0 1 0";
    text += row + "\n";
  }
  writeFile((seq / "calib.txt").string(), text);
  expectInputError([&] { loadSequence(seq.string()); }, (seq / "calib.txt").string(), 0,
                   "expected a stereo baseline in [0.1, 3] m (car), found 0 m");
}

TEST(Plausibility, FolderNamedLikeADataFileIsAnError) {
  TempDir dir;
  const fs::path seq = kittiCopy(dir, 0, [](const std::string& r) { return r; });
  fs::remove(seq / "poses.txt");
  fs::create_directories(seq / "poses.txt");
  expectInputError([&] { loadSequence(seq.string()); }, (seq / "poses.txt").string(), 0,
                   "expected a regular file, found a folder");
}

TEST(Plausibility, ShippedSequencesAreWithinTheLimits) {
  for (const std::string& name : listSequences()) {
    EXPECT_NO_THROW(loadSequence(name)) << name;
  }
}

TEST(ErrorMessages, LongTokensAreCutAndEmptyFilesLeaveNoPrefix) {
  EXPECT_EQ(shortToken("abc"), "abc");
  const std::string long_token(5000000, 'y');
  EXPECT_EQ(shortToken(long_token), std::string(80, 'y') + "… (5000000 bytes)");
  // Never cut inside a UTF-8 character: "é" is 2 bytes, so 79 'a' + "é" cut at 80 keeps 79.
  EXPECT_EQ(shortToken(std::string(79, 'a') + "éé"), std::string(79, 'a') + "… (83 bytes)");
  EXPECT_STREQ(InputError("", 0, "trajectory spline: need at least 2 poses").what(),
               "trajectory spline: need at least 2 poses");
  const InputError located("poses.txt", 0, "what");
  EXPECT_STREQ(located.what(), "poses.txt: what");
  EXPECT_EQ(located.detail(), "what");

  TempDir dir;
  // Below the 1 MiB line bound of the dataset reader (text_file.cpp), which a longer line meets.
  const std::string token(500000, 'y');
  const std::string path =
      writeFile(dir.file("gt.txt"), "1.0 0 0 0 0 0 0 1\n2.0 " + token + " 0 0 0 0 0 1\n");
  try {
    readTumTrajectory(path);
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_LT(std::string(e.what()).size(), 300u);
    EXPECT_NE(std::string(e.what()).find("… (500000 bytes)"), std::string::npos) << e.what();
  }
  writeFile(path, "1.0 0 0 0 0 0 0 1\n2.0 " + long_token + " 0 0 0 0 0 1\n");
  try {
    readTumTrajectory(path);
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ":2: expected a text file with lines of at most 1 "
                                                "MiB"),
              std::string::npos)
        << e.what();
  }
}

// Minor item of issue #32: a KITTI calib.txt whose P1 has the wrong sign (the cameras swapped,
// baseline −0.54 m) or absurd intrinsics passed check and ran with 0–7 % stereo matches. P0 and
// P1 values: fx = [0], cx = [2], tx·fx = [3], fy = [5], cy = [6].
TEST(Plausibility, ImpossibleKittiCalibrationIsAnInputError) {
  struct Case {
    const char* what;
    const char* camera;
    int value;
    const char* text;
    const char* message;
  };
  const std::vector<Case> cases = {
      {"P1 of the wrong sign", "P1:", 3, "3.798145000000e+02",
       "expected cam1 to the right of cam0"},
      {"fx = 1e30", "P0:", 0, "1e30", "cam0: expected fx in [20, 10000] px"},
      {"fy = 2", "P1:", 5, "2", "cam1: expected fy in [20, 10000] px"},
      {"principal point far outside", "P0:", 2, "-5e5", "cam0: expected the principal point"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    TempDir dir;
    const fs::path seq = kittiCopy(dir, 0, [](const std::string& r) { return r; });
    std::istringstream in(test::readGz((kShipped / "kitti/10/calib.txt").string()));
    std::string text, row;
    while (std::getline(in, row)) {
      if (row.rfind(c.camera, 0) == 0) {
        std::istringstream fields(row.substr(3));
        std::vector<std::string> v(12);
        for (auto& value : v) fields >> value;
        v[static_cast<std::size_t>(c.value)] = c.text;
        row = c.camera;
        for (const auto& value : v) row += " " + value;
      }
      text += row + "\n";
    }
    writeFile((seq / "calib.txt").string(), text);
    expectInputError([&] { loadSequence(seq.string()); }, (seq / "calib.txt").string(), 0,
                     c.message);
  }
}

}  // namespace
}  // namespace marglab
