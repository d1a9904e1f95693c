// The Snavely camera's analytic Jacobians (core/ba/snavely_camera.h) against central differences
// in float and double, rotations near zero and near π included, and against Ceres' automatic
// differentiation of the same residual written with the stored angle-axis.
#include <ceres/autodiff_cost_function.h>
#include <gtest/gtest.h>

#include <random>

#include "core/ba/ceres_ba.h"
#include "core/ba/snavely_camera.h"
#include "core/geometry/so3.h"
#include "geometry/geometry_test_utils.h"

namespace marglab {
namespace {

using test::fdJacobian;
using test::fdTolerance;
using test::hardRotationVectors;
using test::matricesNear;

// A camera with rotation ω and a point 3–5 units in front of it (P_z < 0), inside a ±30° cone:
// every factor of the projection is O(1), so the bounds below are the plain ε-bounds.
template <typename S>
struct CameraCase {
  SnavelyCamera<S> camera;
  Vec3<S> X;
  Vec<S, 2> z;
};

template <typename S>
CameraCase<S> makeSetup(const Vec3<S>& omega, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vec<double, 9> params;
  params << omega.template cast<double>(), u(rng), u(rng), u(rng), 1.5 + 0.5 * u(rng), 0.1 * u(rng),
      0.02 * u(rng);
  CameraCase<S> s;
  s.camera = SnavelyCamera<S>::fromBal(params);
  const Vec3<double> P(0.5 * u(rng), 0.5 * u(rng), -4.0 + u(rng));
  const Mat3<double> R = expSO3<double>(params.head<3>());
  s.X = (R.transpose() * (P - params.segment<3>(3))).cast<S>();
  s.z = Vec<S, 2>(S(0.1 * u(rng)), S(0.1 * u(rng)));
  return s;
}

// Bound on the third derivatives of r for a unit change of any variable: r is f·d·p with p a
// quotient by P_z; each derivative of P w.r.t. δφ brings a factor ‖P‖, each derivative of the
// quotient a factor (1 + ‖p‖)/|P_z|, so |r'''| ≤ 3! f d (1 + ‖p‖)⁴ (‖P‖ / |P_z|)³ (and ‖X‖_∞² more
// for the point, whose differences step h·|X_i|).
template <typename S>
S thirdDerivativeScale(const CameraCase<S>& s) {
  const Vec3<S> P = s.camera.R_c_w * s.X + s.camera.t_c_w;
  const S p = P.template head<2>().norm() / std::abs(P.z());
  const S ratio = std::max(S(1), P.norm() / std::abs(P.z()));
  return S(6) * s.camera.f * S(1.2) * std::pow(S(1) + p, S(4)) * ratio * ratio * ratio;
}

template <typename S>
class SnavelyCameraTest : public ::testing::Test {};
TYPED_TEST_SUITE(SnavelyCameraTest, test::ScalarTypes, test::ScalarNames);

TYPED_TEST(SnavelyCameraTest, CameraJacobianMatchesCentralDifferences) {
  using S = TypeParam;
  std::mt19937 rng(11);
  for (const Vec3<S>& omega : hardRotationVectors<S>()) {
    const CameraCase<S> s = makeSetup<S>(omega, rng);
    Vec<S, 2> r;
    Mat<S, 2, 9> J;
    ASSERT_TRUE(snavelyResidual<S>(s.camera, s.X, s.z, &r, &J));
    const auto residual_at = [&](const Vec<S, 9>& xi) {
      SnavelyCamera<S> moved = s.camera;
      moved.applyIncrement(xi);
      Vec<S, 2> out;
      snavelyResidual<S>(moved, s.X, s.z, &out);
      return out;
    };
    const Mat<S, 2, 9> fd = fdJacobian<S, 2, 9>(residual_at, Vec<S, 9>::Zero());
    EXPECT_TRUE(
        matricesNear(J, fd, fdTolerance<S>(std::max(S(1), r.norm()), thirdDerivativeScale(s))))
        << "ω " << omega.transpose();
  }
}

TYPED_TEST(SnavelyCameraTest, PointJacobianMatchesCentralDifferences) {
  using S = TypeParam;
  std::mt19937 rng(12);
  for (const Vec3<S>& omega : hardRotationVectors<S>()) {
    const CameraCase<S> s = makeSetup<S>(omega, rng);
    Vec<S, 2> r;
    Mat<S, 2, 3> J;
    ASSERT_TRUE(snavelyResidual<S>(s.camera, s.X, s.z, &r, nullptr, &J));
    const auto residual_at = [&](const Vec3<S>& X) {
      Vec<S, 2> out;
      snavelyResidual<S>(s.camera, X, s.z, &out);
      return out;
    };
    const S step_scale = std::max(S(1), s.X.cwiseAbs().maxCoeff());
    const Mat<S, 2, 3> fd = fdJacobian<S, 2, 3>(residual_at, s.X);
    EXPECT_TRUE(matricesNear(J, fd,
                             fdTolerance<S>(std::max(S(1), r.norm()) * step_scale,
                                            thirdDerivativeScale(s) * step_scale * step_scale)))
        << "ω " << omega.transpose();
  }
}

TYPED_TEST(SnavelyCameraTest, PointBehindTheCameraIsReported) {
  using S = TypeParam;
  SnavelyCamera<S> camera;
  Vec<S, 2> r;
  EXPECT_TRUE(snavelyResidual<S>(camera, Vec3<S>(0, 0, -2), Vec<S, 2>::Zero(), &r));
  EXPECT_FALSE(snavelyResidual<S>(camera, Vec3<S>(0, 0, 2), Vec<S, 2>::Zero(), &r));
  EXPECT_TRUE(r.allFinite());  // kept in the cost, as rootba and Ceres do
}

TYPED_TEST(SnavelyCameraTest, BalParametersRoundTrip) {
  using S = TypeParam;
  std::mt19937 rng(13);
  for (const Vec3<S>& omega : hardRotationVectors<S>()) {
    const CameraCase<S> s = makeSetup<S>(omega, rng);
    const SnavelyCamera<S> again = SnavelyCamera<S>::fromBal(s.camera.toBal());
    // R → ω → R: a few roundings of S in each direction (log near π included: so3.h).
    EXPECT_TRUE(matricesNear(again.R_c_w, s.camera.R_c_w, 32 * test::kEps<S>));
  }
}

TEST(SnavelyCameraCeres, AnalyticJacobiansMatchAutodiffOfTheStoredParameters) {
  std::mt19937 rng(14);
  for (const Eigen::Vector3d& omega : hardRotationVectors<double>()) {
    const CameraCase<double> s = makeSetup<double>(omega, rng);
    const Vec<double, 9> params = s.camera.toBal();
    ceres::AutoDiffCostFunction<SnavelyResidual, 2, 9, 3> cost(new SnavelyResidual{s.z});
    Eigen::Vector2d r_ceres;
    Eigen::Matrix<double, 2, 9, Eigen::RowMajor> J_cam_ceres;
    Eigen::Matrix<double, 2, 3, Eigen::RowMajor> J_pt_ceres;
    const double* parameters[] = {params.data(), s.X.data()};
    double* jacobians[] = {J_cam_ceres.data(), J_pt_ceres.data()};
    ASSERT_TRUE(cost.Evaluate(parameters, r_ceres.data(), jacobians));

    Eigen::Vector2d r;
    Mat<double, 2, 9> J_xi;
    Mat<double, 2, 3> J_X;
    snavelyResidual<double>(s.camera, s.X, s.z, &r, &J_xi, &J_X);
    // ∂r/∂ω = −∂r/∂P (P − t)^ J_l(ω) = (∂r/∂δφ + ∂r/∂δt · t^) J_l(ω)   (snavely_camera.h).
    const Mat<double, 2, 3> J_omega =
        (J_xi.middleCols<3>(3) + J_xi.leftCols<3>() * hat<double>(s.camera.t_c_w)) *
        leftJacobianSO3<double>(params.head<3>());
    // Both sides: sums of a few dozen rounded products of O(1) factors.
    const double tol = 64 * test::kEps<double> * (1 + J_cam_ceres.cwiseAbs().maxCoeff());
    EXPECT_TRUE(matricesNear(r, r_ceres, tol));
    // For θ² ≤ ε Ceres rotates by I + ω^ (AngleAxisRotatePoint), whose derivative drops the
    // first-order term of exp: its ∂r/∂ω is off by up to θ ‖X‖ ‖∂r/∂P‖ there.
    const double theta = params.head<3>().norm();
    const double ceres_series =
        theta * theta <= test::kEps<double> ? theta * s.X.norm() * J_xi.leftCols<3>().norm() : 0;
    EXPECT_TRUE(matricesNear(J_omega, J_cam_ceres.leftCols<3>(), tol + ceres_series))
        << "ω " << omega.transpose();
    EXPECT_TRUE(matricesNear(J_xi.leftCols<3>(), J_cam_ceres.middleCols<3>(3), tol));
    EXPECT_TRUE(matricesNear(J_xi.rightCols<3>(), J_cam_ceres.rightCols<3>(), tol));
    EXPECT_TRUE(matricesNear(J_X, J_pt_ceres, tol));
  }
}

}  // namespace
}  // namespace marglab
