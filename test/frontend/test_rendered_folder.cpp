// `marglab datasets render` (core/frontend/rendered_folder.h), one camera-model family each:
// EuRoC V1_03_difficult (radial-tangential), TUM-VI room1 (Kannala–Brandt), KITTI 00 (rectified
// pinhole). The folder loads with the shipped calibration, the frame times and the spline as
// ground truth, its images are the renderer's; `datasets check` and `run` accept it without
// borrowing the shipped data (no fallback_sequence). Bad arguments exit 1 and leave no folder,
// SIGINT exits 130 and leaves none either; a seed gives the same folder byte for byte.
// The truth of world_render.h: sprite centres equal OpenCV's projection through the same model,
// and the view-cone culling drops no drawn point.

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/calib3d.hpp>
#include <string>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/data/parsers.h"
#include "core/data/sequence.h"
#include "core/frontend/image_file.h"
#include "core/frontend/image_folder.h"
#include "core/frontend/rendered_folder.h"
#include "core/io/results_file.h"
#include "core/sim/feature_tracker.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::quote;
using test::runCli;

struct Family {
  const char* dataset;
  double start_s;  // into the ground truth: in motion
};
constexpr Family kEuroc{"euroc/V1_03_difficult", 8.0};
constexpr Family kTumvi{"tumvi/room1", 10.0};
constexpr Family kKitti{"kitti/00", 0.0};
constexpr int kFrames = 30;

class RenderedFolder : public test::TempDirTest {
 protected:
  // Renders the family's folder through the CLI; returns its path.
  fs::path render(const Family& family, int frames) const {
    const fs::path out = dir_ / "folder";
    const auto result =
        runCli(fmt::format("datasets render --dataset {} --frames {} --start {} "
                           "--seed 4 -o {}",
                           family.dataset, frames, family.start_s, quote(out)));
    EXPECT_EQ(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find(fmt::format("rendered {} stereo frames", frames)),
              std::string::npos)
        << result.output;
    return out;
  }

  // Every entry of the test folder is the rendered folder: no temporary left behind.
  void expectNoTemporary() const {
    for (const auto& entry : fs::directory_iterator(dir_)) {
      EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos) << entry.path();
    }
  }

  void roundTrip(const Family& family) const;
};

// rotation_tolerance > 0: the loader re-orthonormalizes a rotation it reads (through a quaternion),
// which changes a written one in its last bits.
void expectSameCamera(const CameraCalib& a, const CameraCalib& b, double rotation_tolerance = 0) {
  EXPECT_EQ(a.fx, b.fx);
  EXPECT_EQ(a.fy, b.fy);
  EXPECT_EQ(a.cx, b.cx);
  EXPECT_EQ(a.cy, b.cy);
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.distortion_model, b.distortion_model);
  EXPECT_EQ(a.distortion, b.distortion);
  if (rotation_tolerance > 0) {
    EXPECT_LE((a.R_b_c - b.R_b_c).norm(), rotation_tolerance);
  } else {
    EXPECT_EQ(a.R_b_c, b.R_b_c);
  }
  EXPECT_EQ(a.t_b_c, b.t_b_c);
}

void RenderedFolder::roundTrip(const Family& family) const {
  const fs::path folder = render(family, kFrames);
  expectNoTemporary();
  const RenderPlan plan = planRendering(family.dataset, kFrames, family.start_s, 4);

  // Loaded back: the real calibration, the frame times, the spline as ground truth, own IMU.
  const ImageSequence loaded = loadImageSequence(folder.string());
  const Sequence& seq = loaded.sequence;
  EXPECT_EQ(loaded.fallback, "");
  expectSameCamera(seq.calib.cam0, plan.sequence.calib.cam0);
  expectSameCamera(seq.calib.cam1, plan.sequence.calib.cam1);
  EXPECT_EQ(seq.cam_t_ns, plan.t_ns);
  ASSERT_TRUE(loaded.images.has_value());
  EXPECT_EQ(loaded.images->t_ns, plan.t_ns);
  ASSERT_TRUE(seq.hasTrajectory());
  EXPECT_LE(seq.gt.t_ns.front(), plan.t_ns.front());
  EXPECT_GE(seq.gt.t_ns.back(), plan.t_ns.back());
  for (std::size_t i = 0; i < seq.gt.size(); ++i) {
    const TrajectorySample s = plan.spline->evaluate(seq.gt.t_ns[i]);
    EXPECT_EQ(seq.gt.p_w_b[i], s.p_w_b);
    EXPECT_LE((seq.gt.q_w_b[i].toRotationMatrix() - s.R_w_b).norm(), 1e-14);
  }
  if (seq.kind == DatasetKind::kTumvi) {  // the cameras as sensor.yaml too
    expectSameCamera(readEurocSensorYaml((folder / "mav0/cam0/sensor.yaml").string()),
                     plan.sequence.calib.cam0, 1e-15);
    expectSameCamera(readEurocSensorYaml((folder / "mav0/cam1/sensor.yaml").string()),
                     plan.sequence.calib.cam1, 1e-15);
  }
  if (seq.kind != DatasetKind::kKitti) {
    ASSERT_TRUE(seq.imu.has_value());
    EXPECT_NE(seq.imu_file.find(folder.string()), std::string::npos);
    const ImuNoise &a = seq.imu_noise, &b = plan.sequence.imu_noise;
    EXPECT_EQ(a.gyro_noise_density, b.gyro_noise_density);
    EXPECT_EQ(a.gyro_random_walk, b.gyro_random_walk);
    EXPECT_EQ(a.accel_noise_density, b.accel_noise_density);
    EXPECT_EQ(a.accel_random_walk, b.accel_random_walk);
  }
  // The pixels are the renderer's.
  const RenderedFrame first = WorldRenderer(plan.world, plan.sequence.calib, plan.render)
                                  .render(plan.spline->evaluate(plan.t_ns.front()), 0);
  EXPECT_EQ(cv::norm(decodeImageFile(loaded.images->left.front()), first.left, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(decodeImageFile(loaded.images->right.front()), first.right, cv::NORM_INF), 0);

  const auto check = runCli("datasets check " + quote(folder));
  EXPECT_EQ(check.exit_code, 0) << check.output;
  const fs::path results = dir_ / "run.h5";
  const auto run = runCli(fmt::format("run --dataset {} --variant ns-qr-sqrt-f64 --frames {} -o {}",
                                      quote(folder), kFrames, quote(results)));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const ResultsReader reader(results.string());
  EXPECT_EQ(reader.info().status, "ok");
  EXPECT_EQ(reader.info().metadata.frontend, "images");
  EXPECT_EQ(reader.frames().size(), static_cast<std::size_t>(kFrames));
  for (const auto& [key, value] : reader.info().metadata.extra) {
    EXPECT_NE(key, "fallback_sequence") << value;
  }
}

TEST_F(RenderedFolder, EurocRadtanRoundTrip) { roundTrip(kEuroc); }
TEST_F(RenderedFolder, TumviEquidistantRoundTrip) { roundTrip(kTumvi); }
TEST_F(RenderedFolder, KittiPinholeRoundTrip) { roundTrip(kKitti); }

TEST_F(RenderedFolder, BadArgumentsExitOneAndWriteNothing) {
  const fs::path out = dir_ / "out";
  const auto expectRefused = [&](const std::string& args, const std::string& named) {
    const auto result = runCli("datasets render " + args + " -o " + quote(out));
    EXPECT_EQ(result.exit_code, 1) << args << "\n" << result.output;
    EXPECT_NE(result.output.find(named), std::string::npos) << named << "\n" << result.output;
    EXPECT_FALSE(fs::exists(out)) << args;
    expectNoTemporary();
  };
  expectRefused("--dataset euroc/V1_03_difficult --frames 0", "--frames");
  expectRefused("--dataset euroc/V1_03_difficult --frames -3", "--frames");
  expectRefused("--dataset euroc/V1_03_difficult --frames 100000", "--frames");
  expectRefused("--dataset euroc/V1_03_difficult --frames 2 --start -1", "--start");
  expectRefused("--dataset euroc/V1_03_difficult --frames 2 --start 1e6", "--start");
  expectRefused("--dataset euroc/no_such_sequence --frames 2", "euroc/V1_03_difficult");
  expectRefused("--dataset tumvi/corridor2 --frames 2", "no trajectory");
  expectRefused("--dataset " + quote(dir_) + " --frames 2", "shipped sequence");
  {  // Issue 38 item 8: -o "" rendered, then failed to rename.
    const auto result = test::runShell("cd " + quote(dir_) + " && '" + test::cliPath() +
                                       "' datasets render --dataset kitti/04 --frames 2 -o ''");
    EXPECT_EQ(result.exit_code, 2) << result.output;
    EXPECT_NE(result.output.find("-o is empty"), std::string::npos) << result.output;
    expectNoTemporary();
  }
  {  // a file in the way
    std::ofstream(out) << "x";
    const auto result = runCli("datasets render --dataset kitti/04 --frames 2 -o " + quote(out));
    EXPECT_EQ(result.exit_code, 1) << result.output;
    EXPECT_NE(result.output.find("not an empty folder"), std::string::npos) << result.output;
    EXPECT_EQ(test::readText(out), "x");
    fs::remove(out);
  }

  // An existing non-empty folder is refused and left as it was; an empty one is filled.
  fs::create_directories(out);
  const auto ok = runCli("datasets render --dataset kitti/04 --frames 2 -o " + quote(out));
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
  EXPECT_TRUE(fs::exists(out / "sequences" / "04" / "image_1" / "000001.png"));
  EXPECT_EQ(decodeImageFile((out / "sequences/04/image_0/000000.png").string()).cols, 1226);
  const auto again = runCli("datasets render --dataset kitti/04 --frames 3 -o " + quote(out));
  EXPECT_EQ(again.exit_code, 1) << again.output;
  EXPECT_NE(again.output.find("not an empty folder"), std::string::npos) << again.output;
  EXPECT_FALSE(fs::exists(out / "sequences" / "04" / "image_0" / "000002.png"));
  expectNoTemporary();
}

// SIGINT while the images are written: exit 130, neither the folder nor its temporary remains.
TEST_F(RenderedFolder, InterruptLeavesNothing) {
  const fs::path out = dir_ / "out";
  const pid_t pid = test::startCli(
      {"datasets", "render", "--dataset", "kitti/00", "--frames", "400", "-o", out.string()},
      (dir_ / "log.txt").string());
  // The temporary is a new "out.tmp-XXXXXX" (mkdtemp).
  const auto image = [&] {
    for (const auto& entry : fs::directory_iterator(dir_)) {
      const fs::path candidate = entry.path() / "sequences/00/image_0/000002.png";
      if (entry.path().filename().string().rfind("out.tmp-", 0) == 0 && fs::exists(candidate)) {
        return true;
      }
    }
    return false;
  };
  for (int i = 0; i < 1200 && !image(); ++i) ::usleep(50'000);
  ASSERT_TRUE(image()) << test::readText(dir_ / "log.txt");
  ::kill(pid, SIGINT);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130) << test::readText(dir_ / "log.txt");
  EXPECT_FALSE(fs::exists(out));
  fs::remove(dir_ / "log.txt");
  expectNoTemporary();
}

// Same seed, same folder: every file byte for byte (README.txt names the output folder); another
// seed, other images and IMU noise.
TEST_F(RenderedFolder, DeterministicForASeed) {
  const auto renderTo = [&](const std::string& name, int seed) {
    const auto result =
        runCli(fmt::format("datasets render --dataset euroc/V1_03_difficult --frames 3 --start 20 "
                           "--seed {} -o {}",
                           seed, quote(dir_ / name)));
    EXPECT_EQ(result.exit_code, 0) << result.output;
    return dir_ / name;
  };
  const fs::path a = renderTo("a", 7), b = renderTo("b", 7), c = renderTo("c", 8);
  std::size_t files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(a)) {
    if (!entry.is_regular_file() || entry.path().filename() == "README.txt") continue;
    const fs::path relative = fs::relative(entry.path(), a);
    EXPECT_EQ(test::readText(entry.path()), test::readText(b / relative)) << relative;
    ++files;
  }
  EXPECT_EQ(files, 7u + 2u * 3u);  // data.csv ×3, sensor.yaml ×3, ground truth; 3 frames ×2
  EXPECT_NE(test::readText(a / "mav0/imu0/data.csv"), test::readText(c / "mav0/imu0/data.csv"));
  const std::string first =
      "mav0/cam0/data/" + test::readText(a / "mav0/cam0/data.csv").substr(25, 19) + ".png";
  EXPECT_NE(test::readText(a / first), test::readText(c / first)) << first;
}

// The sprite centre of every drawn point is its projection through the camera model, checked
// against OpenCV's implementation of the same model (radtan: cv::projectPoints with k1 k2 p1 p2;
// Kannala–Brandt: cv::fisheye::projectPoints; KITTI: the pinhole). And the view-cone culling
// draws exactly what testing every point draws.
void checkTruth(const Family& family) {
  const RenderPlan plan = planRendering(family.dataset, 20, family.start_s, 4);
  WorldRenderer renderer(plan.world, plan.sequence.calib, plan.render);
  WorldRenderer everything(plan.world, plan.sequence.calib, plan.render);
  everything.setCulling(false);
  std::size_t checked = 0;
  for (int k = 0; k < 20; k += 6) {
    const TrajectorySample body = plan.spline->evaluate(plan.t_ns[k]);
    const RenderedFrame frame = renderer.render(body, k);
    const RenderedFrame all = everything.render(body, k);
    EXPECT_EQ(frame.centre0, all.centre0);
    EXPECT_EQ(frame.centre1, all.centre1);
    EXPECT_EQ(cv::norm(frame.left, all.left, cv::NORM_INF), 0);
    EXPECT_EQ(cv::norm(frame.right, all.right, cv::NORM_INF), 0);
    for (int camera = 0; camera < 2; ++camera) {
      const CameraCalib& calib = camera == 0 ? plan.sequence.calib.cam0 : plan.sequence.calib.cam1;
      Eigen::Matrix3d R_w_c;
      Eigen::Vector3d p_w_c;
      cameraPose(body, calib, &R_w_c, &p_w_c);
      std::vector<cv::Point3d> points;
      std::vector<Eigen::Vector2d> centres;
      for (const auto& [l, c] : camera == 0 ? frame.centre0 : frame.centre1) {
        const Eigen::Vector3d p_c = R_w_c.transpose() * (plan.world.points_w[l] - p_w_c);
        points.emplace_back(p_c.x(), p_c.y(), p_c.z());
        centres.push_back(c);
      }
      ASSERT_GT(points.size(), 50u);
      const cv::Matx33d K(calib.fx, 0, calib.cx, 0, calib.fy, calib.cy, 0, 0, 1);
      const cv::Vec3d zero(0, 0, 0);
      std::vector<cv::Point2d> projected;
      if (calib.distortion_model == "equidistant") {
        cv::fisheye::projectPoints(points, projected, zero, zero, K, calib.distortion);
      } else {
        const std::vector<double> none(4, 0.0);
        cv::projectPoints(points, zero, zero, K,
                          calib.distortion_model == "radtan" ? calib.distortion : none, projected);
      }
      for (std::size_t i = 0; i < points.size(); ++i) {
        EXPECT_LE((centres[i] - Eigen::Vector2d(projected[i].x, projected[i].y)).norm(), 1e-6)
            << family.dataset << " camera " << camera;
        ++checked;
      }
    }
  }
  std::printf("%s: %zu sprite centres checked\n", family.dataset, checked);
}

TEST(RenderedTruth, RadtanCentresAreOpenCvProjections) { checkTruth(kEuroc); }
TEST(RenderedTruth, EquidistantCentresAreOpenCvFisheyeProjections) { checkTruth(kTumvi); }
TEST(RenderedTruth, PinholeCentresAreProjections) { checkTruth(kKitti); }

}  // namespace
}  // namespace marglab
