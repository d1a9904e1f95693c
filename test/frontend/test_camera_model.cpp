// Camera models of EuRoC (radtan), TUM-VI (equidistant / Kannala–Brandt) and KITTI (rectified):
// undistort → distort and distort → undistort round trips over the image, the distortion
// Jacobians against central differences, in float and double, with the shipped calibrations.

#include <gtest/gtest.h>

#include <cmath>

#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/frontend/camera_model.h"
#include "geometry/geometry_test_utils.h"

namespace marglab {
namespace {

using test::kEps;

template <typename Scalar>
class CameraModelTest : public ::testing::Test {
 protected:
  static CameraModel<Scalar> model(const std::string& sequence) {
    const Sequence seq = loadSequence(sequence, LoadOptions{false});
    return cameraModelFromCalib<Scalar>(seq.calib.cam0, seq.calib_source);
  }
};
TYPED_TEST_SUITE(CameraModelTest, test::ScalarTypes, test::ScalarNames);

// Round-trip bound in pixels. The inverse stops when |d(x) − x_d| ≤ 64 ε max(1, |x_d|)
// (camera_model.cpp); evaluating d once more adds ≤ kEvalUlps ε |x_d|, and the pixel ↔ normalized
// conversions add a few ε of |u| + |c|. Scaled by the focal length into pixels.
template <typename Scalar>
double roundTripTolerance(const CameraModel<Scalar>& cam, double r_d) {
  const double eps = static_cast<double>(kEps<Scalar>);
  const double f = std::max(static_cast<double>(cam.fx), static_cast<double>(cam.fy));
  const double c = std::max(cam.width, cam.height);
  return f * (64.0 + test::kEvalUlps) * eps * std::max(1.0, r_d) + 8.0 * eps * 2.0 * c;
}

// Raw pixels on a grid over the image → pinhole → raw again; returns how many were refused.
template <typename Scalar>
int checkUndistortDistort(const CameraModel<Scalar>& cam, double must_succeed_r_d) {
  using Vec2 = typename CameraModel<Scalar>::Vec2;
  int refused = 0;
  for (int v = 0; v < cam.height; v += 16) {
    for (int u = 0; u < cam.width; u += 16) {
      const Vec2 raw(static_cast<Scalar>(u), static_cast<Scalar>(v));
      const double r_d = std::hypot((u - static_cast<double>(cam.cx)) / cam.fx,
                                    (v - static_cast<double>(cam.cy)) / cam.fy);
      Vec2 pinhole;
      if (!cam.undistortPixel(raw, &pinhole)) {
        EXPECT_GT(r_d, must_succeed_r_d) << "refused " << u << ", " << v;
        ++refused;
        continue;
      }
      const Vec2 back = cam.distortPixel(pinhole);
      EXPECT_TRUE(test::matricesNear(back, raw, roundTripTolerance(cam, r_d)))
          << distortionModelName(cam.model) << " at " << u << ", " << v;
    }
  }
  return refused;
}

TYPED_TEST(CameraModelTest, EurocRadTanUndistortDistortRoundTrip) {
  const auto cam = this->model("euroc/V1_01_easy");
  ASSERT_EQ(cam.model, DistortionModel::kRadTan);
  EXPECT_EQ(checkUndistortDistort(cam, 10.0), 0);  // every pixel of the image
}

TYPED_TEST(CameraModelTest, TumviEquidistantUndistortDistortRoundTrip) {
  const auto cam = this->model("tumvi/room1");
  ASSERT_EQ(cam.model, DistortionModel::kEquidistant);
  // θ_d = |x_d| below 1.3 rad (θ < 1.4 rad, the pinhole limit) must all invert; the corners of the
  // fisheye image (|x_d| up to 1.9) lie beyond 80° and are refused.
  const int refused = checkUndistortDistort(cam, 1.3);
  EXPECT_GT(refused, 0);
}

TYPED_TEST(CameraModelTest, KittiPinholeIsIdentity) {
  using Vec2 = typename CameraModel<TypeParam>::Vec2;
  const auto cam = this->model("kitti/00");
  ASSERT_EQ(cam.model, DistortionModel::kNone);
  const Vec2 raw(TypeParam(100.25), TypeParam(200.5));
  Vec2 pinhole;
  ASSERT_TRUE(cam.undistortPixel(raw, &pinhole));
  EXPECT_TRUE(test::matricesNear(pinhole, raw, roundTripTolerance(cam, 1.0)));
  EXPECT_TRUE(test::matricesNear(cam.distortPixel(pinhole), raw, roundTripTolerance(cam, 1.0)));
}

// Pinhole pixel → raw → pinhole, over a grid that covers the pinhole image.
TYPED_TEST(CameraModelTest, DistortUndistortRoundTrip) {
  using Vec2 = typename CameraModel<TypeParam>::Vec2;
  for (const char* name : {"euroc/V1_01_easy", "tumvi/room1"}) {
    const auto cam = this->model(name);
    for (int v = 0; v < cam.height; v += 24) {
      for (int u = 0; u < cam.width; u += 24) {
        const Vec2 pinhole(static_cast<TypeParam>(u), static_cast<TypeParam>(v));
        const Vec2 raw = cam.distortPixel(pinhole);
        Vec2 back;
        ASSERT_TRUE(cam.undistortPixel(raw, &back)) << name << " " << u << ", " << v;
        const double r = std::hypot((u - static_cast<double>(cam.cx)) / cam.fx,
                                    (v - static_cast<double>(cam.cy)) / cam.fy);
        // Undistorting amplifies the raw pixel's rounding by |∂x/∂x_d| = |J⁻¹| ≤ 1/σ_min(J);
        // σ_min(J) ≥ 0.5 over these images (radtan k1 = −0.28 at r ≤ 1; equidistant θ ≤ 1.1).
        EXPECT_TRUE(test::matricesNear(back, pinhole, 2.0 * roundTripTolerance(cam, r)))
            << name << " at " << u << ", " << v;
      }
    }
  }
}

TYPED_TEST(CameraModelTest, DistortionJacobianMatchesCentralDifferences) {
  using Vec2 = typename CameraModel<TypeParam>::Vec2;
  using Mat2 = typename CameraModel<TypeParam>::Mat2;
  for (const char* name : {"euroc/V1_01_easy", "tumvi/room1", "kitti/00"}) {
    const auto cam = this->model(name);
    for (const Vec2& x :
         {Vec2(TypeParam(0.3), TypeParam(-0.2)), Vec2(TypeParam(-0.7), TypeParam(0.5)),
          Vec2(TypeParam(0.05), TypeParam(0.01)), Vec2(TypeParam(1.0), TypeParam(0.4))}) {
      Mat2 J;
      cam.distortNormalized(x, &J);
      const auto f = [&](const Vec2& p) { return cam.distortNormalized(p); };
      const Mat2 J_fd = test::fdJacobian<TypeParam, 2, 2>(f, x);
      // |f| ≤ 2 and |f'''| ≤ 10 for |x| ≤ 1.1 (radtan: 6 k1 + 60 k2 r²; atan-based KB: O(1)).
      EXPECT_TRUE(test::matricesNear(J, J_fd, test::fdTolerance<TypeParam>(2, 10)))
          << name << " at " << x.transpose();
    }
  }
}

TYPED_TEST(CameraModelTest, BadCalibrationIsAnInputError) {
  CameraCalib calib;
  calib.fx = calib.fy = 400;
  calib.distortion_model = "fov";
  calib.distortion = {0.9};
  EXPECT_THROW(cameraModelFromCalib<TypeParam>(calib, "cam.yaml"), InputError);
  calib.distortion_model = "radtan";
  EXPECT_THROW(cameraModelFromCalib<TypeParam>(calib, "cam.yaml"), InputError);
}

}  // namespace
}  // namespace marglab
