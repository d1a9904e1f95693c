// The motion-stereo measurement of a rectified pair's disparities (core/frontend/stereo_bias.h,
// `marglab datasets stereo-bias`):
//  - triangulateFromMotion (f32, f64): noise-free pixels give the point to the working precision
//    times the problem's conditioning; its covariance is (JᵀJ)⁻¹ with J from central differences
//    of the projection (independent of the analytic Jacobian); a point behind a camera is refused;
//  - motionStereoSamples on a synthetic street with an injected disparity offset (and a baseline
//    error) recovers the injected values, and nothing when none is injected;
//  - the CLI on a rendered KITTI folder (exact pixels) whose right camera's cx is moved by a known
//    amount: the fragment holds the correction back, `run --config` records it, and the bad inputs
//    (no poses, frames out of range, too few frames, a malformed range) exit with their errors
//    and no fragment.

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <sstream>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/common/scalar.h"
#include "core/frontend/stereo_bias.h"
#include "core/io/results_file.h"
#include "core/pipeline/run_config.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::quote;
using test::runCli;

template <typename Scalar>
class MotionTriangulationTest : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
class ScalarNames {
 public:
  template <typename T>
  static std::string GetName(int) {
    return std::is_same_v<T, float> ? "f32" : "f64";
  }
};
TYPED_TEST_SUITE(MotionTriangulationTest, Scalars, ScalarNames);

// A car-like sequence: five poses 1 m apart along the optical axis, turning slightly, looking at
// a point 12 m ahead and 3 m to the side (KITTI's f, cx, cy).
template <typename Scalar>
struct MotionScene {
  PinholeCamera<Scalar> cam;
  std::vector<SE3<Scalar>> T_c_w;
  Eigen::Matrix<Scalar, 3, 1> p_w{Scalar(3), Scalar(-1), Scalar(12)};
  MotionScene() {
    cam.fx = cam.fy = Scalar(707.0912);
    cam.cx = Scalar(601.8873);
    cam.cy = Scalar(183.1104);
    for (int k = 0; k < 5; ++k) {
      const SE3<double> T_w_c(
          Eigen::AngleAxisd(0.01 * k, Eigen::Vector3d::UnitY()).toRotationMatrix(),
          Eigen::Vector3d(0.05 * k, 0, 1.0 * k));
      T_c_w.push_back(T_w_c.inverse().cast<Scalar>());
    }
  }
  std::vector<Eigen::Matrix<Scalar, 2, 1>> pixels() const {
    std::vector<Eigen::Matrix<Scalar, 2, 1>> uv;
    for (const auto& T : T_c_w) {
      Eigen::Matrix<Scalar, 2, 1> p;
      EXPECT_TRUE(cam.project(T * p_w, &p));
      uv.push_back(p);
    }
    return uv;
  }
};

TYPED_TEST(MotionTriangulationTest, NoiseFreePixelsGiveThePoint) {
  using S = TypeParam;
  const MotionScene<S> scene;
  const auto tri = triangulateFromMotion(scene.T_c_w, scene.pixels(), scene.cam);
  ASSERT_TRUE(tri.has_value());
  // The pixels carry rounding ε·|u| ≈ ε·1000 px; the point moves by Σ^½ per px of it, and the
  // residual is at that rounding.
  const S eps = NumericTraits<S>::kEpsilon;
  const S px_rounding = eps * S(1000);
  const S point_sigma = std::sqrt(tri->cov_per_px2.diagonal().maxCoeff());
  EXPECT_LE((tri->p_w - scene.p_w).norm(), S(10) * (px_rounding * point_sigma + eps * S(12)));
  EXPECT_LE(tri->rms_px, S(10) * px_rounding);
}

TYPED_TEST(MotionTriangulationTest, CovarianceIsTheInverseOfJtJByCentralDifferences) {
  using S = TypeParam;
  const MotionScene<S> scene;
  const auto tri = triangulateFromMotion(scene.T_c_w, scene.pixels(), scene.cam);
  ASSERT_TRUE(tri.has_value());
  // J by central differences in double (independent of the analytic ∂π/∂p), at the true point.
  const MotionScene<double> ref;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  const double h = 1e-4;
  for (const auto& T : ref.T_c_w) {
    Eigen::Matrix<double, 2, 3> J;
    for (int i = 0; i < 3; ++i) {
      Eigen::Vector3d a = ref.p_w, b = ref.p_w;
      a(i) += h;
      b(i) -= h;
      Eigen::Vector2d ua, ub;
      ASSERT_TRUE(ref.cam.project(T * a, &ua) && ref.cam.project(T * b, &ub));
      J.col(i) = (ua - ub) / (2 * h);
    }
    H += J.transpose() * J;
  }
  const Eigen::Matrix3d cov = H.inverse();
  // Central differences: O(h²) truncation (~1e-8 relative here); the cast to S: ε_S times the
  // condition number of H, which the inverse amplifies.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(H);
  const double condition = eig.eigenvalues()(2) / eig.eigenvalues()(0);
  const double tol = 1e-6 + 100 * double(NumericTraits<S>::kEpsilon) * condition;
  EXPECT_LE((tri->cov_per_px2.template cast<double>() - cov).norm(), tol * cov.norm())
      << "condition " << condition;
}

TYPED_TEST(MotionTriangulationTest, APointBehindACameraIsRefused) {
  using S = TypeParam;
  MotionScene<S> scene;
  auto uv = scene.pixels();
  scene.p_w.z() = S(-5);  // behind every camera; the pixels of the mirrored point
  for (std::size_t k = 0; k < uv.size(); ++k) {
    const auto p = scene.T_c_w[k] * scene.p_w;
    uv[k] = {scene.cam.fx * p.x() / p.z() + scene.cam.cx,
             scene.cam.fy * p.y() / p.z() + scene.cam.cy};
  }
  EXPECT_FALSE(triangulateFromMotion(scene.T_c_w, uv, scene.cam).has_value());
  EXPECT_FALSE(triangulateFromMotion(scene.T_c_w, std::vector<Eigen::Matrix<S, 2, 1>>(1), scene.cam)
                   .has_value());
}

// A street: points 6–60 m ahead on both sides, the car driving 1 m per frame for 20 frames; the
// right pixel u1 = f (x − b) / z + cx − offset − s · f b / z (so that d = d_true + offset + s d),
// pixel noise 0.05 px (fixed seed).
struct Street {
  TrackStream stream;
  std::vector<SE3<double>> T_w_c;
  RectifiedStereo stereo{707.0912, 601.8873, 601.8873, 183.1104, 0.537151};
};

Street street(double offset, double s) {
  Street out;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> x(-12, 12), y(-2, 1.5), z(6, 60);
  std::normal_distribution<double> noise(0, 0.05);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 600; ++i) points.emplace_back(x(rng), y(rng), z(rng) + 20);
  const RectifiedStereo& st = out.stereo;
  for (int k = 0; k < 20; ++k) {
    out.T_w_c.emplace_back(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 1.0 * k));
    TrackFrame frame;
    frame.t_ns = 100'000'000LL * k;
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3d p = points[i] - out.T_w_c.back().translation();
      if (p.z() < 3) continue;
      StereoObservation obs;
      obs.track_id = static_cast<int64_t>(i);
      obs.uv0 = {st.f * p.x() / p.z() + st.cx0 + noise(rng),
                 st.f * p.y() / p.z() + st.cy + noise(rng)};
      if (obs.uv0.x() < 0 || obs.uv0.x() > 1226 || obs.uv0.y() < 0 || obs.uv0.y() > 370) continue;
      const double d = st.f * st.baseline_m / p.z();
      obs.has_right = true;
      obs.uv1 = {st.f * (p.x() - st.baseline_m) / p.z() + st.cx1 - offset - s * d + noise(rng),
                 obs.uv0.y() + noise(rng)};
      frame.observations.push_back(obs);
    }
    out.stream.frames.push_back(frame);
  }
  return out;
}

TEST(MotionStereo, RecoversAnInjectedDisparityOffset) {
  for (const double offset : {0.0, -0.6, 0.35}) {
    const Street s = street(offset, 0);
    int used = 0;
    const auto samples = motionStereoSamples(s.stream, s.T_w_c, s.stereo, 0, 19, {}, &used);
    ASSERT_GT(samples.size(), 500u);
    const DisparityErrorSummary sum = summarizeDisparityErrors(samples, 0.05, 1226, 370);
    // Noise 0.05 px on u0 and u1 (0.07 px on d), the motion disparity within max_sigma 0.15 px:
    // the median of > 500 samples is within a few 0.01 px; the offset fit recovers c with s ≈ 0.
    EXPECT_NEAR(sum.median, offset, 0.02) << "injected " << offset;
    EXPECT_NEAR(sum.fit_c, offset, 4 * sum.fit_c_se + 0.01) << "injected " << offset;
    EXPECT_NEAR(sum.fit_s, 0, 4 * sum.fit_s_se + 0.002);
    EXPECT_NEAR(sum.dv, 0, 0.01);
  }
}

TEST(MotionStereo, SeparatesABaselineErrorFromAnOffset) {
  const Street s = street(-0.2, -0.01);  // d = d_true − 0.2 px − 1 % of d_true
  const auto samples = motionStereoSamples(s.stream, s.T_w_c, s.stereo, 0, 19, {});
  const DisparityErrorSummary sum = summarizeDisparityErrors(samples, 0.05, 1226, 370);
  EXPECT_NEAR(sum.fit_c, -0.2, 4 * sum.fit_c_se + 0.01);
  EXPECT_NEAR(sum.fit_s, -0.01, 4 * sum.fit_s_se + 0.001);
}

TEST(MotionStereo, ConfigShiftOfTheRightCameraEntersTheStereoDisparity) {
  // The same street seen through a calibration whose cx1 is moved by +0.6: the measured offset
  // moves by +0.6 (the run's model of the disparity is (u0 − u1) − (cx0 − cx1)).
  Street s = street(-0.6, 0);
  s.stereo.cx1 += 0.6;
  const auto samples = motionStereoSamples(s.stream, s.T_w_c, s.stereo, 0, 19, {});
  EXPECT_NEAR(summarizeDisparityErrors(samples, 0.05, 1226, 370).median, 0.0, 0.02);
}

// Poses whose scale absorbed the bias (a VO's own trajectory, ×λ about the first pose): the motion
// disparities become d / λ, which moves s and leaves the intercept c — the offset stays
// observable without ground truth, the median does not.
TEST(MotionStereo, TheFitInterceptIsTheOffsetWhateverTheTrajectoryScale) {
  Street s = street(-0.5, 0);
  for (SE3<double>& T : s.T_w_c) T = SE3<double>(T.unitQuaternion(), 1.02 * T.translation());
  const auto samples = motionStereoSamples(s.stream, s.T_w_c, s.stereo, 0, 19, {});
  const DisparityErrorSummary sum = summarizeDisparityErrors(samples, 0.05, 1226, 370);
  const OffsetScaleFit fit = fitOffsetScale(samples, 0.05);
  EXPECT_EQ(fit.c, sum.fit_c);
  EXPECT_NEAR(fit.c, -0.5, 4 * fit.c_se + 0.01);
  EXPECT_NEAR(fit.s, 1 - 1 / 1.02, 4 * fit.s_se + 0.001);  // d_motion = d / 1.02
  EXPECT_GT(std::abs(sum.median + 0.5), 0.1);              // the median mixes in the scale
}

TEST(StereoBiasCalibration, ApplyMovesTheRightCameraPrincipalPointOnly) {
  StereoCalib calib;
  calib.cam0.cx = calib.cam1.cx = 601.8873;
  const StereoCalib before = calib;
  applyCalibration(CalibrationSettings{}, &calib);
  EXPECT_EQ(calib.cam1.cx, before.cam1.cx);  // the default changes nothing, bit for bit
  applyCalibration(CalibrationSettings{0.25}, &calib);
  EXPECT_EQ(calib.cam1.cx, before.cam1.cx + 0.25);
  EXPECT_EQ(calib.cam0.cx, before.cam0.cx);
  EXPECT_EQ(calib.cam1.cy, before.cam1.cy);
}

// One rendered KITTI folder for the CLI tests (exact pixels; rendering takes a few seconds).
class StereoBiasCli : public test::TempDirTest {
 protected:
  static void SetUpTestSuite() {
    folder_ = new fs::path(fs::temp_directory_path() /
                           ("marglab_" + std::to_string(::getpid()) + "_stereo_bias_r00"));
    fs::remove_all(*folder_);
    const auto r =
        runCli("datasets render --dataset kitti/00 --frames 24 --seed 4 -o " + quote(*folder_));
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  static void TearDownTestSuite() {
    fs::remove_all(*folder_);
    delete folder_;
  }
  static fs::path calibPath() { return *folder_ / "sequences" / "00" / "calib.txt"; }
  // A copy of the rendered folder with P1's cx moved by `shift` px.
  fs::path shiftedCopy(double shift) const {
    const fs::path copy = dir_ / "shifted";
    fs::copy(*folder_, copy, fs::copy_options::recursive);
    std::ifstream in(calibPath());
    std::string text, line;
    while (std::getline(in, line)) {
      if (line.rfind("P1:", 0) == 0) {
        std::istringstream fields(line.substr(3));
        std::vector<double> v(12);
        for (double& x : v) fields >> x;
        v[2] += shift;
        line = "P1:";
        for (double x : v) line += fmt::format(" {:.12e}", x);
      }
      text += line + "\n";
    }
    std::ofstream(copy / "sequences" / "00" / "calib.txt") << text;
    return copy;
  }
  static double fragmentShift(const fs::path& toml) {
    const std::string text = test::readText(toml);
    std::smatch m;
    static const std::regex key(R"(\n\[calibration\]\nright_cx_shift_px = (-?[0-9.]+)\n)");
    EXPECT_TRUE(std::regex_search(text, m, key)) << text;
    return m.empty() ? NAN : std::stod(m[1].str());
  }
  static fs::path* folder_;
};
fs::path* StereoBiasCli::folder_ = nullptr;

// The rendered pixels are exact: the measurement there is −0.01 px (results/real_kitti06/README.md
// §2); a right camera whose calib.txt cx is 0.6 px too small reads every disparity 0.6 px too
// small, and the fragment moves it back.
TEST_F(StereoBiasCli, ARightCameraShiftedInTheCalibrationIsMeasuredAndCorrected) {
  const fs::path copy = shiftedCopy(-0.6);
  const fs::path out = dir_ / "bias.toml";
  const auto r =
      runCli(fmt::format("datasets stereo-bias --dataset {} -o {}", quote(copy), quote(out)));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("held out"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("vertical misalignment"), std::string::npos) << r.output;
  EXPECT_NEAR(fragmentShift(out), 0.6, 0.05) << r.output;

  // The fragment is a config: the run on the shifted copy records it in config_toml, and the
  // verb with it measures what is left (the rendered folder's own −0.01 px).
  const fs::path run = dir_ / "run.h5";
  const auto rr =
      runCli(fmt::format("run --dataset {} --variant ns-qr-sqrt-f64 --frames 5 "
                         "--config {} -o {}",
                         quote(copy), quote(out), quote(run)));
  ASSERT_EQ(rr.exit_code, 0) << rr.output;
  const std::string config = ResultsReader(run.string()).info().metadata.config_toml;
  RunConfig recorded;
  recorded.loadTomlString(config, "config_toml");
  EXPECT_DOUBLE_EQ(recorded.calibration.right_cx_shift_px, fragmentShift(out));
  const fs::path again = dir_ / "again.toml";
  const auto ra = runCli(fmt::format("datasets stereo-bias --dataset {} --config {} -o {}",
                                     quote(copy), quote(out), quote(again)));
  ASSERT_EQ(ra.exit_code, 0) << ra.output;
  EXPECT_NEAR(fragmentShift(again), fragmentShift(out), 0.03) << ra.output;
}

// Without ground truth: the run's own trajectory as the poses (--poses RUN.tum); the offset is the
// fit's intercept, and the fragment holds its correction.
TEST_F(StereoBiasCli, ARunsOwnTrajectoryGivesTheOffsetAsTheFitIntercept) {
  const fs::path copy = shiftedCopy(-0.6);
  const fs::path run = dir_ / "run.h5";
  const auto rr = runCli(
      fmt::format("run --dataset {} --variant ns-qr-sqrt-f64 -o {}", quote(copy), quote(run)));
  ASSERT_EQ(rr.exit_code, 0) << rr.output;
  const fs::path out = dir_ / "bias.toml";
  const auto r = runCli(fmt::format("datasets stereo-bias --dataset {} --poses {} -o {}",
                                    quote(copy), quote(dir_ / "run.tum"), quote(out)));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("not ground truth: offset = the fit's intercept c"), std::string::npos)
      << r.output;
  std::smatch m;
  const std::regex fit(R"(c = (-?[0-9.]+) \+- )");
  ASSERT_TRUE(std::regex_search(r.output, m, fit)) << r.output;
  EXPECT_NEAR(fragmentShift(out), -std::stod(m[1].str()), 1e-4) << r.output;
  // The estimator's trajectory is not exactly a scale of the truth: on these 24 rendered frames
  // the intercept recovers most of the 0.6 px (0.52 px on 30 frames, results/stereo_bias_kitti06).
  EXPECT_GT(fragmentShift(out), 0.4) << r.output;
  EXPECT_LT(fragmentShift(out), 0.7) << r.output;
}

TEST_F(StereoBiasCli, BadInputsExitWithWhatWasExpectedAndWriteNothing) {
  const fs::path out = dir_ / "bias.toml";
  const auto expectError = [&](const std::string& args, int code, const std::string& message) {
    const auto r = runCli("datasets stereo-bias " + args + " -o " + quote(out));
    EXPECT_EQ(r.exit_code, code) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << args << "\n" << r.output;
    EXPECT_FALSE(fs::exists(out)) << args;
  };
  const std::string dataset = "--dataset " + quote(*folder_);
  expectError(
      dataset + " --frames 0:40", 1,
      "expected FIRST:LAST with 0 <= FIRST <= LAST <= 23 (the folder has 24 stereo frames)");
  expectError(dataset + " --frames 10:14", 1, "5 frames, expected at least 8");
  expectError(dataset + " --frames 9:2", 2, "expected FIRST:LAST");
  expectError(dataset + " --frames 3", 2, "expected FIRST:LAST");
  expectError("--dataset euroc/V1_01_easy_images", 1, "expected a KITTI-layout folder");
  // A KITTI folder without poses (the shipped layout, a name no shipped sequence has).
  const fs::path bare = dir_ / "bare";
  const fs::path seq = *folder_ / "sequences" / "00";
  fs::create_directories(bare);
  for (const char* name : {"calib.txt", "times.txt"}) fs::copy(seq / name, bare / name);
  for (const char* name : {"image_0", "image_1"}) {
    fs::copy(seq / name, bare / name, fs::copy_options::recursive);
  }
  expectError("--dataset " + quote(bare), 1, "no ground-truth poses");
  // Poses that miss a measured frame (a TUM file of the first 5 frames only).
  const fs::path tum = dir_ / "short.tum";
  {
    std::ifstream times(seq / "times.txt");
    std::ofstream out_tum(tum);
    double t = 0;
    for (int k = 0; k < 5 && times >> t; ++k)
      out_tum << fmt::format("{:.9f} 0 0 {} 0 0 0 1\n", t, k);
  }
  expectError(dataset + " --poses " + quote(tum), 1, "frame 5 (t = ");
}

}  // namespace
}  // namespace marglab
