// SE(3) against independent computations: the 4×4 matrix exponential in long double, 4×4 matrix
// algebra, central differences, float vs double; and the estimator's ⊞/⊟ increment and
// relative-pose Jacobians.

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <unsupported/Eigen/MatrixFunctions>

#include "core/geometry/se3.h"
#include "test/geometry/geometry_test_utils.h"

namespace marglab::test {
namespace {

using Mat3L = Eigen::Matrix<long double, 3, 3>;
using Mat4L = Eigen::Matrix<long double, 4, 4>;
using Vec6L = Eigen::Matrix<long double, 6, 1>;

Mat3L hatL(const Eigen::Matrix<long double, 3, 1>& w) {
  Mat3L W;
  W << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return W;
}

Mat4L twistL(const Vec6L& xi) {
  Mat4L X = Mat4L::Zero();
  X.topLeftCorner<3, 3>() = hatL(xi.tail<3>());
  X.topRightCorner<3, 1>() = xi.head<3>();
  return X;
}

// ξ = [υ; ω] with ω from the hard rotation set and |υ| uniform in [0.1, 3].
template <typename Scalar>
std::vector<Vec<Scalar, 6>> hardTwists() {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> len(0.1, 3.0);
  std::vector<Vec<Scalar, 6>> out;
  for (const Vec3<Scalar>& omega : hardRotationVectors<Scalar>()) {
    Vec<Scalar, 6> xi;
    xi.template head<3>() = randomUnit<Scalar>(rng) * Scalar(len(rng));
    xi.template tail<3>() = omega;
    out.push_back(xi);
  }
  return out;
}

template <typename Scalar>
SE3<Scalar> randomPose(std::mt19937& rng, double t_scale) {
  std::uniform_real_distribution<double> angle(0.0, M_PI);
  const Vec3<Scalar> omega = randomUnit<Scalar>(rng) * Scalar(angle(rng));
  return SE3<Scalar>(expSO3(omega), randomUnit<Scalar>(rng) * Scalar(t_scale));
}

template <typename Scalar>
class SE3Test : public ::testing::Test {};
TYPED_TEST_SUITE(SE3Test, ScalarTypes, ScalarNames);

TYPED_TEST(SE3Test, ExpMatchesMatrixExponential) {
  using S = TypeParam;
  for (const Vec<S, 6>& xi : hardTwists<S>()) {
    const Mat4L ref = twistL(xi.template cast<long double>()).exp();
    const double tol = kEvalUlps * kEps<S> * (1 + xi.norm());
    EXPECT_TRUE(matricesNear(SE3<S>::exp(xi).matrix(), ref, tol)) << "xi " << xi.transpose();
  }
}

// log(exp(ξ)) = ξ for θ < π; Jl⁻¹ (|Jl⁻¹| ≤ π²/4 in the υ block) bounds the rounding growth.
TYPED_TEST(SE3Test, LogExpRoundTrip) {
  using S = TypeParam;
  for (const Vec<S, 6>& xi : hardTwists<S>()) {
    const SE3<S> T = SE3<S>::exp(xi);
    const Vec<S, 6> log_T = T.log();
    const double tol = kEvalUlps * kEps<S> * (1 + xi.norm()) * M_PI * M_PI;
    EXPECT_TRUE(matricesNear(SE3<S>::exp(log_T).matrix(), T.matrix(), tol));
    if (xi.template tail<3>().norm() < S(M_PI)) {
      EXPECT_TRUE(matricesNear(log_T, xi, tol)) << "xi " << xi.transpose();
    }
  }
}

TYPED_TEST(SE3Test, GroupOperationsMatchMatrices) {
  using S = TypeParam;
  std::mt19937 rng(5);
  for (int i = 0; i < 20; ++i) {
    const SE3<S> A = randomPose<S>(rng, 3.0);
    const SE3<S> B = randomPose<S>(rng, 3.0);
    const Vec3<S> p = randomUnit<S>(rng) * S(5);
    const double tol = kEvalUlps * kEps<S> * 10;
    EXPECT_TRUE(matricesNear((A * B).matrix(), A.matrix() * B.matrix(), tol));
    EXPECT_TRUE(matricesNear(A.inverse().matrix(), A.matrix().inverse(), tol));
    EXPECT_TRUE(matricesNear((A * A.inverse()).matrix(), Mat<S, 4, 4>::Identity(), tol));
    const Vec3<S> Ap = (A.matrix() * p.homogeneous()).template head<3>();
    EXPECT_TRUE(matricesNear(A * p, Ap, tol));
    EXPECT_TRUE(matricesNear(A.rotationMatrix(), A.unitQuaternion().toRotationMatrix(), 0.0));
    const SE3<S> A_from_R(A.rotationMatrix(), A.translation());
    EXPECT_TRUE(matricesNear(A_from_R.matrix(), A.matrix(), tol));
  }
}

TYPED_TEST(SE3Test, BoxPlusDefinitionAndRoundTrips) {
  using S = TypeParam;
  std::mt19937 rng(8);
  for (int i = 0; i < 20; ++i) {
    const SE3<S> T = randomPose<S>(rng, 3.0);
    const SE3<S> T_a = randomPose<S>(rng, 3.0);
    Vec<S, 6> delta;
    delta.template head<3>() = randomUnit<S>(rng) * S(0.7);
    delta.template tail<3>() = randomUnit<S>(rng) * S(0.3 * (i % 10));  // θ up to 2.7
    const double tol = kEvalUlps * kEps<S> * 10;
    const SE3<S> T_plus = boxPlus(T, delta);
    EXPECT_TRUE(matricesNear(T_plus.rotationMatrix(),
                             expSO3<S>(delta.template tail<3>()) * T.rotationMatrix(), tol));
    EXPECT_TRUE(
        matricesNear(T_plus.translation(), T.translation() + delta.template head<3>(), tol));
    EXPECT_TRUE(matricesNear(boxMinus(T_plus, T), delta, tol));
    EXPECT_TRUE(matricesNear(boxPlus(T, boxMinus(T_a, T)).matrix(), T_a.matrix(), tol));
    EXPECT_TRUE(matricesNear(boxMinus(T, T), Vec<S, 6>::Zero(), 0.0));
  }
}

// T_ct_ch = (T_w_it T_i_ct)⁻¹ T_w_ih T_i_ch and its ⊞ Jacobians by central differences.
TYPED_TEST(SE3Test, RelativePoseValueAndJacobians) {
  using S = TypeParam;
  std::mt19937 rng(9);
  const Vec<S, 6> zero = Vec<S, 6>::Zero();
  for (int i = 0; i < 10; ++i) {
    const SE3<S> T_w_ih = randomPose<S>(rng, 3.0);
    const SE3<S> T_w_it = randomPose<S>(rng, 3.0);
    const bool with_extrinsics = i % 2 == 0;
    const SE3<S> T_i_ch = with_extrinsics ? randomPose<S>(rng, 0.2) : SE3<S>();
    const SE3<S> T_i_ct = with_extrinsics ? randomPose<S>(rng, 0.2) : SE3<S>();
    Mat<S, 6, 6> d_h, d_t;
    const SE3<S> rel = with_extrinsics ? relativePose(T_w_ih, T_i_ch, T_w_it, T_i_ct, &d_h, &d_t)
                                       : relativePose(T_w_ih, T_w_it, &d_h, &d_t);
    const SE3<S> expected = (T_w_it * T_i_ct).inverse() * T_w_ih * T_i_ch;
    EXPECT_TRUE(matricesNear(rel.matrix(), expected.matrix(), kEvalUlps * kEps<S> * 10));
    const Mat<S, 6, 6> d_h_fd = fdJacobian<S, 6, 6>(
        [&](const Vec<S, 6>& d) {
          return boxMinus(relativePose(boxPlus(T_w_ih, d), T_i_ch, T_w_it, T_i_ct), rel);
        },
        zero);
    const Mat<S, 6, 6> d_t_fd = fdJacobian<S, 6, 6>(
        [&](const Vec<S, 6>& d) {
          return boxMinus(relativePose(T_w_ih, T_i_ch, boxPlus(T_w_it, d), T_i_ct), rel);
        },
        zero);
    // |f| is small but its rounding follows the translations (≤ 7 m) entering it.
    const S tol = fdTolerance<S>(S(7), S(7));
    EXPECT_TRUE(matricesNear(d_h, d_h_fd, tol));
    EXPECT_TRUE(matricesNear(d_t, d_t_fd, tol));
  }
}

TEST(SE3FloatVsDouble, CastAndExponentialAgree) {
  std::mt19937 rng(10);
  for (const Vec<float, 6>& xi : hardTwists<float>()) {
    const Vec<double, 6> xi_d = xi.cast<double>();
    const double scale = 1 + xi_d.norm();
    const double tol = kEvalUlps * kEps<float> * scale * M_PI * M_PI;
    EXPECT_TRUE(matricesNear(SE3<float>::exp(xi).matrix(), SE3<double>::exp(xi_d).matrix(), tol));
    EXPECT_TRUE(matricesNear(SE3<double>::exp(xi_d).cast<float>().matrix(),
                             SE3<double>::exp(xi_d).matrix(), tol));
  }
}

}  // namespace
}  // namespace marglab::test
