// Window::frameReprojectionErrors, the input of the tracking monitor's consistency rule
// (core/pipeline/tracking_monitor.h): against pixel offsets put in by construction — each
// observation is a world point projected through an independently composed camera pose
// (T_w_c1⁻¹ p_w, not the window's relative poses), moved by a known offset — for a hosted landmark,
// a world-point landmark, a point behind the camera (+∞) and the observations the rule must skip
// (the frame's own hosted landmarks, a landmark seen once).

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/estimator/window.h"
#include "core/geometry/stereographic.h"
#include "estimator/vo_scenario.h"
#include "test/geometry/geometry_test_utils.h"

namespace marglab::test {
namespace {

template <typename Scalar>
class WindowConsistency : public ::testing::Test {};
TYPED_TEST_SUITE(WindowConsistency, ScalarTypes, ScalarNames);

TYPED_TEST(WindowConsistency, ErrorsArePixelOffsetsOfTheSharedObservations) {
  using Scalar = TypeParam;
  using W = Window<Scalar>;
  const StereoRig<double> rig = kittiLikeRig();
  W window(EstimatorSettings{}, rig, std::nullopt);
  const SE3<double> T_w_c0;  // frame 0 at the origin
  const SE3<double> T_w_c1(expSO3(Eigen::Vector3d(0.01, -0.03, 0.02)),
                           Eigen::Vector3d(0.3, -0.1, 1.2));
  window.frames[0].T_w_i = T_w_c0.cast<Scalar>();
  window.frames[1].T_w_i = T_w_c1.cast<Scalar>();

  // The observation in frame 1 of p_w, offset by d (pixels).
  auto observed = [&](const Eigen::Vector3d& p_w, const Eigen::Vector2d& d) {
    Eigen::Vector2d uv = Eigen::Vector2d::Zero();
    EXPECT_TRUE(rig.cam0.project(T_w_c1.inverse() * p_w, &uv));
    typename W::Observation obs;
    obs.uv0 = (uv + d).cast<Scalar>();
    return obs;
  };
  auto hostedIn0 = [&](const Eigen::Vector3d& p_w) {
    typename W::Landmark lm;
    lm.host = 0;
    lm.param = landmarkFromPoint<double>(p_w).cast<Scalar>();
    lm.obs[0].uv0.setZero();  // the host observation is not checked
    return lm;
  };
  const Eigen::Vector3d p_a(1.5, -0.4, 12.0), p_b(-3.0, 0.8, 25.0), p_c(0.5, 0.2, -8.0);
  window.landmarks[1] = hostedIn0(p_a);
  window.landmarks[1].obs[1] = observed(p_a, {3.0, 4.0});  // 5 px
  window.landmarks[2].host = -1;                           // a world point
  window.landmarks[2].param = p_b.cast<Scalar>();
  window.landmarks[2].obs[0].uv0.setZero();
  window.landmarks[2].obs[1] = observed(p_b, {-0.6, 0.8});  // 1 px
  window.landmarks[3] = hostedIn0(p_c);                     // behind both cameras
  window.landmarks[3].obs[1].uv0 = Vec<Scalar, 2>(600, 180);
  window.landmarks[4].host = 1;  // hosted in frame 1: its own observation, skipped
  window.landmarks[4].param = landmarkFromPoint<double>(Eigen::Vector3d(0, 0, 10)).cast<Scalar>();
  window.landmarks[4].obs[1].uv0 = Vec<Scalar, 2>(1, 1);
  window.landmarks[5].host = -1;  // seen by frame 1 alone: skipped
  window.landmarks[5].param = p_b.cast<Scalar>();
  window.landmarks[5].obs[1] = observed(p_b, {50, 0});

  const std::vector<Scalar> errors = window.frameReprojectionErrors(1);
  ASSERT_EQ(errors.size(), 3u);  // landmarks 1, 2, 3 in id order
  // Pixel coordinates of ~600 carry the rounding of Scalar; the projection chain adds a few ulps.
  const double tol = 64 * 600 * std::numeric_limits<Scalar>::epsilon();
  EXPECT_NEAR(errors[0], 5.0, tol);
  EXPECT_NEAR(errors[1], 1.0, tol);
  EXPECT_TRUE(std::isinf(errors[2]));
  // Frame 0 hosts 1 and 3; of the rest it shares only the world point 2 (observed at (0, 0)).
  EXPECT_EQ(window.frameReprojectionErrors(0).size(), 1u);
}

}  // namespace
}  // namespace marglab::test
