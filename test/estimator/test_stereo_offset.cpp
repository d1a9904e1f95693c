// The right camera's cx offset as a window variable ([estimator] estimate_right_cx_offset,
// core/estimator/window.h): its Jacobian column against central differences of the window's own
// residual and cost (f32, f64), and a simulated run whose right camera is loaded with its cx moved
// by a known amount recovers the amount and the trajectory.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/common/error.h"
#include "core/estimator/estimator.h"
#include "core/estimator/window.h"
#include "core/geometry/stereographic.h"
#include "core/pipeline/run.h"
#include "core/pipeline/run_config.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/world.h"
#include "estimator/vo_scenario.h"
#include "test/geometry/geometry_test_utils.h"

namespace marglab::test {
namespace {

template <typename Scalar>
class StereoOffsetJacobian : public ::testing::Test {};
TYPED_TEST_SUITE(StereoOffsetJacobian, ScalarTypes, ScalarNames);

// Two frames and one landmark hosted in frame 0, seen by both cameras of both frames; its
// observations are the projections moved by less than the Huber threshold (weight 1), so the
// residual is affine in the offset c and the central difference has no truncation error.
template <typename Scalar>
Window<Scalar> twoFrameWindow(const StereoRig<double>& rig) {
  EstimatorSettings config;
  config.estimate_right_cx_offset = true;
  Window<Scalar> window(config, rig, std::nullopt);
  const SE3<double> T_w_c1(expSO3(Eigen::Vector3d(0.01, -0.03, 0.02)),
                           Eigen::Vector3d(0.3, -0.1, 1.2));
  window.frames[0].T_w_i = SE3<Scalar>();
  window.frames[1].T_w_i = T_w_c1.cast<Scalar>();
  const Eigen::Vector3d p_w(1.5, -0.4, 12.0);
  typename Window<Scalar>::Landmark lm;
  lm.host = 0;
  lm.param = landmarkFromPoint<double>(p_w).cast<Scalar>();
  const SE3<double> T_c0_c1 = rig.T_c0_c1();
  const SE3<double> poses[2] = {SE3<double>(), T_w_c1};
  for (int f = 0; f < 2; ++f) {
    Eigen::Vector2d uv0 = Eigen::Vector2d::Zero(), uv1 = Eigen::Vector2d::Zero();
    EXPECT_TRUE(rig.cam0.project(poses[f].inverse() * p_w, &uv0));
    EXPECT_TRUE(rig.cam1.project((poses[f] * T_c0_c1).inverse() * p_w, &uv1));
    lm.obs[f] = {(uv0 + Eigen::Vector2d(0.2, -0.1)).cast<Scalar>(), true,
                 (uv1 + Eigen::Vector2d(-0.3 + 0.1 * f, 0.15)).cast<Scalar>()};
  }
  window.landmarks[7] = lm;
  window.setStereoOffset(Scalar(0.25));
  return window;
}

TYPED_TEST(StereoOffsetJacobian, ColumnIsTheCentralDifferenceOfTheResidualAndTheCost) {
  using Scalar = TypeParam;
  const StereoRig<double> rig = kittiLikeRig();
  Window<Scalar> window = twoFrameWindow<Scalar>(rig);
  const std::set<int64_t> frames = {0, 1};
  auto linearize = [&](Scalar c, LandmarkJacobians<Scalar>* lin) {
    window.setStereoOffset(c);
    const auto rel = window.relativePoses(WithJacobians::kYes);
    ASSERT_TRUE(window.linearizeLandmark(7, window.landmarks.at(7), frames, rel, lin));
  };
  auto cost = [&](Scalar c) {
    window.setStereoOffset(c);
    return static_cast<double>(
        window.landmarkCost(window.landmarks.at(7), window.relativePoses(WithJacobians::kNo)));
  };
  const Scalar c = Scalar(0.25), h = Scalar(0.125);  // h and c ± h exact in binary
  LandmarkJacobians<Scalar> lin, plus, minus;
  linearize(c, &lin);
  linearize(c + h, &plus);
  linearize(c - h, &minus);
  ASSERT_TRUE(lin.stereo_offset);
  ASSERT_EQ(lin.frames.size(), 2u);
  ASSERT_EQ(lin.J_p.cols(), 2 * kPoseDim + 1);  // [host | target | c]
  const VecXd column = lin.J_p.col(lin.J_p.cols() - 1).template cast<double>();
  const VecXd fd = (plus.r - minus.r).template cast<double>() / (2.0 * static_cast<double>(h));
  // Rows: cam0, cam1 of frame 0 (the host), then of frame 1; only the right camera's u rows move.
  const double sigma = EstimatorSettings{}.obs_std_px;
  for (int i = 0; i < lin.J_p.rows(); ++i) {
    EXPECT_EQ(column[i], i % 4 == 2 ? Scalar(1 / sigma) : Scalar(0)) << "row " << i;
  }
  // The residuals carry cx ≈ 600 px rounded to Scalar (a few ulps each), divided by 2h.
  const double ulp_px = 600.0 * std::numeric_limits<Scalar>::epsilon();
  const double tol = 8.0 * ulp_px / sigma / (2.0 * static_cast<double>(h));
  EXPECT_LE((column - fd).cwiseAbs().maxCoeff(), tol);
  // The cost the LM accepts steps by: dE/dc = rᵀ ∂r/∂c, both at the same camera.
  const double grad = column.dot(lin.r.template cast<double>());
  const double fd_cost = (cost(c + h) - cost(c - h)) / (2.0 * static_cast<double>(h));
  EXPECT_NEAR(grad, fd_cost,
              8.0 * ulp_px / (sigma * sigma) * lin.r.size() / static_cast<double>(h));
  EXPECT_GT(std::abs(grad), 0.1);  // the test is not vacuous
}

// A camera driving on a circle (vo_scenario.h, as test_vo.cpp's), the tracks simulated with the true rig, the
// estimator given the rig with the right camera's cx moved by −0.6 px: the window's offset comes
// back to +0.6 px and the trajectory to the truth.
struct Recovery {
  double offset = std::numeric_limits<double>::quiet_NaN();
  double max_position_error = 0;
};

template <typename Scalar>
Recovery runWithShiftedRightCamera(bool estimate, int frames) {
  CircleTrajectory trajectory;
  const StereoCalib calib = kittiLikeCalib();
  TrackerOptions tracker;
  tracker.grid_cell_px = 30;
  tracker.max_depth = 250;
  tracker.noise = false;
  tracker.outliers = false;
  std::vector<int64_t> t_ns;
  for (int i = 0; i < frames; ++i) t_ns.push_back(int64_t{100'000'000} * i);
  const World world = makeWorld(trajectory, defaultWorldOptions(DatasetKind::kKitti), 3);
  const TrackStream stream = simulateTracks(trajectory, calib, t_ns, world, tracker, 5);
  StereoCalib loaded = calib;
  loaded.cam1.cx -= 0.6;
  EstimatorSettings config;
  config.min_frames_after_kf = 1;
  config.estimate_right_cx_offset = estimate;
  auto truth = [&trajectory](int64_t t) {
    const TrajectorySample s = trajectory.evaluate(t);
    return SE3<double>(s.R_w_b, s.p_w_b);
  };
  SlidingWindowEstimator<Scalar> estimator(config, Variant::parse("ns-qr-sqrt-f64"),
                                           rigFromCalib(loaded), truth(t_ns.front()));
  Recovery out;
  for (const TrackFrame& frame : stream.frames) {
    const FrameResult result = estimator.processFrame(frame);
    EXPECT_TRUE(result.status.ok()) << result.status.toString();
    out.offset = result.right_cx_offset_px;
    out.max_position_error =
        std::max(out.max_position_error, (result.p_est - truth(frame.t_ns).translation()).norm());
  }
  return out;
}

TEST(StereoOffsetRun, NoiseFreeTracksRecoverAnInjectedOffset) {
  const Recovery off = runWithShiftedRightCamera<double>(false, 40);
  const Recovery on = runWithShiftedRightCamera<double>(true, 40);
  EXPECT_TRUE(std::isnan(off.offset));
  // Noise-free tracks: the minimum is the true offset with zero residual; LM stops once its steps
  // are below stop_max_step (1e-4), so the estimate is within a few of those of the truth.
  EXPECT_NEAR(on.offset, 0.6, 10 * EstimatorSettings{}.stop_max_step);
  EXPECT_LT(on.max_position_error, 1e-3);    // the truth to a millimetre, as test_vo's runs
  EXPECT_GT(off.max_position_error, 10e-3);  // the offset does bias the run without it
}

// The keys: off by default, the prior's σ in (0, 100] px, and only with strategy "discard".
TEST(StereoOffsetConfig, KeysRangesAndTheStrategyRelation) {
  RunConfig config;
  EXPECT_FALSE(config.estimator.estimate_right_cx_offset);
  config.loadTomlString("[estimator]\nestimate_right_cx_offset = true\n", "test.toml");
  EXPECT_TRUE(config.estimator.estimate_right_cx_offset);
  EXPECT_NO_THROW(config.validate());
  RunConfig round_trip;
  round_trip.loadTomlString(config.toToml(), "round_trip.toml");
  EXPECT_TRUE(round_trip.estimator.estimate_right_cx_offset);
  for (const char* bad : {"0", "-1", "101"}) {
    RunConfig range = config;
    try {
      range.loadTomlString(std::string("[estimator]\nright_cx_offset_prior_px = ") + bad + "\n",
                           "bad.toml");
      range.validate();
      FAIL() << "right_cx_offset_prior_px = " << bad << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.toml:2"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("right_cx_offset_prior_px"), std::string::npos)
          << e.what();
    }
  }
  for (const char* strategy : {"dense", "nfr"}) {
    RunConfig relation = config;
    relation.loadTomlString(std::string("[marginalization]\nstrategy = \"") + strategy + "\"\n",
                            "bad.toml");
    try {
      relation.validate();
      FAIL() << "estimate_right_cx_offset accepted with strategy " << strategy;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("estimate_right_cx_offset"), std::string::npos)
          << e.what();
    }
  }
}

}  // namespace
}  // namespace marglab::test
