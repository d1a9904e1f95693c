// Pinhole camera and stereo rig on EuRoC's calibration (cam0/cam1 intrinsics, ≈ 0.11 m baseline):
// project/unproject round trips, projection Jacobian by central differences, the minimum-depth and
// image-border rules, and noise-free midpoint triangulation.

#include <gtest/gtest.h>

#include <cmath>

#include "core/geometry/camera.h"
#include "test/geometry/geometry_test_utils.h"

namespace marglab::test {
namespace {

template <typename Scalar>
StereoRig<Scalar> euroCLikeRig(double baseline = 0.110) {
  StereoRig<double> rig;
  rig.cam0 = PinholeCamera<double>{458.654, 457.296, 367.215, 248.375, 752, 480};
  rig.cam1 = PinholeCamera<double>{457.587, 456.134, 379.999, 255.238, 752, 480};
  // Body-to-camera extrinsics of the order of EuRoC's T_BS; cam1 ≈ baseline to the right of cam0
  // with a small relative rotation.
  rig.T_i_c0 = SE3<double>(expSO3(Eigen::Vector3d(-0.03, 0.02, 1.56)),
                           Eigen::Vector3d(-0.0216, -0.0647, 0.0098));
  const SE3<double> T_c0_c1(expSO3(Eigen::Vector3d(0.002, -0.001, 0.0005)),
                            Eigen::Vector3d(baseline, -0.0004, 0.0008));
  rig.T_i_c1 = rig.T_i_c0 * T_c0_c1;
  return rig.cast<Scalar>();
}

template <typename Scalar>
class CameraTest : public ::testing::Test {};
TYPED_TEST_SUITE(CameraTest, ScalarTypes, ScalarNames);

template <typename Scalar>
std::vector<Vec3<Scalar>> pointsInView(const PinholeCamera<Scalar>& cam, double min_depth,
                                       double max_depth, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, cam.width - 1.0);
  std::uniform_real_distribution<double> v(0.0, cam.height - 1.0);
  std::uniform_real_distribution<double> depth(min_depth, max_depth);
  std::vector<Vec3<Scalar>> out;
  for (int i = 0; i < n; ++i) {
    const double z = depth(rng);
    out.emplace_back(Scalar((u(rng) - cam.cx) / cam.fx * z), Scalar((v(rng) - cam.cy) / cam.fy * z),
                     Scalar(z));
  }
  return out;
}

TYPED_TEST(CameraTest, ProjectUnprojectRoundTrip) {
  using S = TypeParam;
  const PinholeCamera<S> cam = euroCLikeRig<S>().cam0;
  for (const Vec3<S>& p : pointsInView(cam, 0.2, 40.0, 50, 31)) {
    Vec<S, 2> uv;
    ASSERT_TRUE(cam.project(p, &uv));
    EXPECT_TRUE(cam.inImage(uv, S(-1)));
    // Pixels carry rounding ε·|uv|, i.e. ε·|uv|/f in the normalized plane (|uv|/f < 2 here).
    EXPECT_TRUE(matricesNear(cam.unproject(uv), p.normalized(), kEvalUlps * kEps<S> * 2));
    Vec<S, 2> uv2;
    ASSERT_TRUE(cam.project(cam.unproject(uv) * S(3.7), &uv2));
    // u = fx x/z + cx rounds relative to the summands: ε (|uv − c| + |c|).
    const S pixel_scale =
        (uv - Vec<S, 2>(cam.cx, cam.cy)).norm() + Vec<S, 2>(cam.cx, cam.cy).norm();
    EXPECT_TRUE(matricesNear(uv2, uv, kEvalUlps * kEps<S> * pixel_scale));
    EXPECT_NEAR(cam.unproject(uv).norm(), S(1), kEvalUlps * kEps<S>);
  }
}

TYPED_TEST(CameraTest, ProjectionJacobianMatchesCentralDifferences) {
  using S = TypeParam;
  const PinholeCamera<S> cam = euroCLikeRig<S>().cam0;
  for (const Vec3<S>& p : pointsInView(cam, 0.5, 10.0, 20, 32)) {
    Vec<S, 2> uv;
    Mat<S, 2, 3> J;
    ASSERT_TRUE(cam.project(p, &uv, &J));
    const auto fd = fdJacobian<S, 2, 3>(
        [&](const Vec3<S>& x) {
          Vec<S, 2> r;
          cam.project(x, &r);
          return r;
        },
        p);
    // |f| ≤ |uv|; ∂³(fx x/z) = O(fx (1 + |x/z|)/z³) with the step scaled by max(1, |p_i|).
    const S z = p.z();
    const S f3 = cam.fx * S(6) * (S(1) + p.template head<2>().norm() / z) / (z * z * z) *
                 std::max(S(1), p.cwiseAbs().maxCoeff()) * std::max(S(1), p.cwiseAbs().maxCoeff());
    EXPECT_TRUE(matricesNear(J, fd, fdTolerance<S>(uv.norm(), f3))) << "p " << p.transpose();
  }
}

TYPED_TEST(CameraTest, MinimumDepthAndImageBorder) {
  using S = TypeParam;
  const PinholeCamera<S> cam = euroCLikeRig<S>().cam0;
  Vec<S, 2> uv(S(-7), S(-7));
  EXPECT_FALSE(cam.project(Vec3<S>(S(0.1), S(0.2), S(0)), &uv));
  EXPECT_FALSE(cam.project(Vec3<S>(S(0.1), S(0.2), S(-1)), &uv));
  EXPECT_FALSE(cam.project(Vec3<S>(S(0.1), S(0.2), S(0.5) * cam.min_depth), &uv));
  EXPECT_FALSE(cam.project(Vec3<S>(S(0.1), S(0.2), std::numeric_limits<S>::quiet_NaN()), &uv));
  EXPECT_TRUE(matricesNear(uv, Vec<S, 2>(S(-7), S(-7)), 0.0));  // untouched on failure
  EXPECT_TRUE(cam.project(Vec3<S>(S(0), S(0), cam.min_depth), &uv));
  EXPECT_TRUE(matricesNear(uv, Vec<S, 2>(cam.cx, cam.cy), 0.0));

  EXPECT_TRUE(cam.inImage(Vec<S, 2>(S(0), S(0))));
  EXPECT_TRUE(cam.inImage(Vec<S, 2>(S(751), S(479))));
  EXPECT_FALSE(cam.inImage(Vec<S, 2>(S(751.5), S(10))));
  EXPECT_FALSE(cam.inImage(Vec<S, 2>(S(10), S(-0.5))));
  EXPECT_TRUE(cam.inImage(Vec<S, 2>(S(20), S(459)), S(20)));
  EXPECT_FALSE(cam.inImage(Vec<S, 2>(S(19.9), S(100)), S(20)));
  EXPECT_FALSE(cam.inImage(Vec<S, 2>(S(100), S(459.1)), S(20)));
}

// Noise-free pixels: the rays meet, and the midpoint recovers the point up to the pixel rounding
// ε |uv|/f (< 2ε in direction) amplified by depth/baseline (the inverse parallax).
TYPED_TEST(CameraTest, TriangulationRecoversNoiseFreePoint) {
  using S = TypeParam;
  const StereoRig<S> rig = euroCLikeRig<S>();
  const SE3<S> T_c1_c0 = rig.T_c0_c1().inverse();
  const S baseline = rig.T_c0_c1().translation().norm();
  int n_tested = 0;
  for (const Vec3<S>& p : pointsInView(rig.cam0, 0.3, 60.0, 100, 33)) {
    Vec<S, 2> uv0, uv1;
    ASSERT_TRUE(rig.cam0.project(p, &uv0));
    if (!rig.cam1.project(T_c1_c0 * p, &uv1) || !rig.cam1.inImage(uv1)) continue;
    ++n_tested;
    Vec3<S> p_est;
    ASSERT_TRUE(rig.triangulate(uv0, uv1, &p_est)) << "p " << p.transpose();
    const S d = p.norm();
    EXPECT_TRUE(matricesNear(p_est, p, kEvalUlps * kEps<S> * 2 * d * (S(1) + d / baseline)))
        << "p " << p.transpose();
    // Float agrees with double on the same pixels.
    if constexpr (std::is_same_v<S, float>) {
      const StereoRig<double> rig_d = euroCLikeRig<double>();
      Vec3<double> p_d;
      ASSERT_TRUE(
          rig_d.triangulate(uv0.template cast<double>(), uv1.template cast<double>(), &p_d));
      EXPECT_TRUE(matricesNear(p_est, p_d, kEvalUlps * kEps<S> * 2 * d * (1 + d / baseline)));
    }
  }
  EXPECT_GT(n_tested, 50);
}

TYPED_TEST(CameraTest, TriangulationRejectsDegenerateConfigurations) {
  using S = TypeParam;
  const StereoRig<S> rig = euroCLikeRig<S>();
  const SE3<S> T_c1_c0 = rig.T_c0_c1().inverse();
  Vec3<S> p_est(S(-7), S(-7), S(-7));
  Vec<S, 2> uv0, uv1;

  // Parallax 0.11 m / 500 m = 2.2e-4 rad < 1e-3.
  const Vec3<S> far(S(1), S(-2), S(500));
  ASSERT_TRUE(rig.cam0.project(far, &uv0));
  ASSERT_TRUE(rig.cam1.project(T_c1_c0 * far, &uv1));
  EXPECT_FALSE(rig.triangulate(uv0, uv1, &p_est));
  TriangulationOptions<S> lenient;
  lenient.min_parallax = S(1e-4);
  EXPECT_TRUE(rig.triangulate(uv0, uv1, &p_est, lenient));

  // Baseline 0.01 m < 0.05 m.
  const StereoRig<S> narrow = euroCLikeRig<S>(0.01);
  const Vec3<S> near(S(0.1), S(0.1), S(1));
  ASSERT_TRUE(narrow.cam0.project(near, &uv0));
  ASSERT_TRUE(narrow.cam1.project(narrow.T_c0_c1().inverse() * near, &uv1));
  Vec3<S> untouched(S(-7), S(-7), S(-7));
  EXPECT_FALSE(narrow.triangulate(uv0, uv1, &untouched));
  EXPECT_TRUE(matricesNear(untouched, Vec3<S>(S(-7), S(-7), S(-7)), 0.0));

  // Diverging rays: they meet behind the cameras.
  ASSERT_TRUE(rig.cam0.project(Vec3<S>(S(-0.1), S(0), S(1)), &uv0));
  ASSERT_TRUE(rig.cam1.project(T_c1_c0.unitQuaternion() * Vec3<S>(S(0.1), S(0), S(1)), &uv1));
  EXPECT_FALSE(rig.triangulate(uv0, uv1, &untouched));
}

}  // namespace
}  // namespace marglab::test
