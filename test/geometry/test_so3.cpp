// SO(3) kernels against independent computations: the matrix exponential and the power series
// Jl(φ) = Σ Φⁿ/(n+1)! in long double, central differences, and the float-vs-double results.

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <unsupported/Eigen/MatrixFunctions>

#include "core/geometry/so3.h"
#include "test/geometry/geometry_test_utils.h"

namespace marglab::test {
namespace {

using Mat3L = Eigen::Matrix<long double, 3, 3>;

Mat3L hatL(const Eigen::Matrix<long double, 3, 1>& w) {
  Mat3L W;
  W << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return W;
}

// Σ_{n≥0} Φⁿ/(n+1)! in long double; |Φ| ≤ π, so 40 terms are exact to long double precision.
Mat3L leftJacobianSeries(const Mat3L& Phi) {
  Mat3L sum = Mat3L::Identity();
  Mat3L term = Mat3L::Identity();
  for (int n = 1; n < 40; ++n) {
    term = term * Phi / static_cast<long double>(n + 1);
    sum += term;
  }
  return sum;
}

// log of a rotation near the reference ref, allowing the result to leave [0, π] (the other
// representation θ − 2π along the same axis), so that differences across θ = π stay smooth.
template <typename Scalar>
Vec3<Scalar> logNear(const Mat3<Scalar>& R, const Vec3<Scalar>& ref) {
  const Vec3<Scalar> w = logSO3(R);
  const Scalar theta = w.norm();
  if (theta == Scalar(0)) return w;
  const Vec3<Scalar> alt = w - Scalar(2 * M_PI) * w / theta;
  return (alt - ref).norm() < (w - ref).norm() ? alt : w;
}

template <typename Scalar>
class SO3Test : public ::testing::Test {};
TYPED_TEST_SUITE(SO3Test, ScalarTypes, ScalarNames);

TYPED_TEST(SO3Test, HatIsCrossProductAndVeeInvertsIt) {
  using S = TypeParam;
  std::mt19937 rng(1);
  for (int i = 0; i < 10; ++i) {
    const Vec3<S> a = randomUnit<S>(rng) * S(2);
    const Vec3<S> b = randomUnit<S>(rng);
    EXPECT_TRUE(matricesNear(hat(a) * b, a.cross(b), 4 * kEps<S> * 2));
    EXPECT_TRUE(matricesNear(vee(hat(a)), a, 0.0));
    EXPECT_TRUE(matricesNear(hat(a) + hat(a).transpose(), Mat3<S>::Zero(), 0.0));
  }
}

TYPED_TEST(SO3Test, ExpMatchesMatrixExponential) {
  using S = TypeParam;
  for (const Vec3<S>& phi : hardRotationVectors<S>()) {
    const Mat3L ref = hatL(phi.template cast<long double>()).exp();
    EXPECT_TRUE(matricesNear(expSO3(phi), ref, kEvalUlps * kEps<S>)) << "phi " << phi.transpose();
    EXPECT_TRUE(matricesNear(expSO3Quaternion(phi).toRotationMatrix(), ref, kEvalUlps * kEps<S>))
        << "phi " << phi.transpose();
    const Mat3<S> R = expSO3(phi);
    EXPECT_TRUE(matricesNear(R.transpose() * R, Mat3<S>::Identity(), kEvalUlps * kEps<S>));
    EXPECT_NEAR(R.determinant(), S(1), kEvalUlps * kEps<S>);
  }
}

// log(exp(φ)) = φ with relative accuracy O(ε) for θ < π (absolute near π); at θ ≥ π (float's
// nearest value to π exceeds it) the other representation is returned, so exp(log R) = R is
// checked instead.
TYPED_TEST(SO3Test, LogExpRoundTrip) {
  using S = TypeParam;
  for (const Vec3<S>& phi : hardRotationVectors<S>()) {
    const S theta = phi.norm();
    const Mat3<S> R = expSO3(phi);
    const Vec3<S> w = logSO3(R);
    EXPECT_LE(w.norm(), S(M_PI) * (1 + kEps<S>));
    EXPECT_TRUE(matricesNear(expSO3(w), R, kEvalUlps * kEps<S>)) << "phi " << phi.transpose();
    EXPECT_TRUE(matricesNear(logSO3(expSO3Quaternion(phi)), w, kEvalUlps * kEps<S> * M_PI));
    if (theta < S(M_PI)) {
      EXPECT_TRUE(matricesNear(w, phi, kEvalUlps * kEps<S> * theta))
          << "theta " << theta << " phi " << phi.transpose();
    }
  }
}

// Rotation by exactly π about an axis: log returns ±π·axis.
TYPED_TEST(SO3Test, LogAtExactlyPi) {
  using S = TypeParam;
  std::mt19937 rng(3);
  for (int i = 0; i < 5; ++i) {
    const Vec3<S> a = randomUnit<S>(rng);
    const Mat3<S> R = S(2) * a * a.transpose() - Mat3<S>::Identity();  // exactly θ = π
    const Vec3<S> w = logSO3(R);
    EXPECT_NEAR(w.norm(), S(M_PI), kEvalUlps * kEps<S> * M_PI);
    EXPECT_NEAR(std::abs(w.normalized().dot(a)), S(1), kEvalUlps * kEps<S>);
  }
}

TYPED_TEST(SO3Test, JacobiansMatchLongDoubleSeries) {
  using S = TypeParam;
  for (const Vec3<S>& phi : hardRotationVectors<S>()) {
    const Mat3L Jl = leftJacobianSeries(hatL(phi.template cast<long double>()));
    const Mat3L Jr = leftJacobianSeries(hatL(-phi.template cast<long double>()));
    EXPECT_TRUE(matricesNear(leftJacobianSO3(phi), Jl, kEvalUlps * kEps<S>))
        << "phi " << phi.transpose();
    EXPECT_TRUE(matricesNear(rightJacobianSO3(phi), Jr, kEvalUlps * kEps<S>));
    // The inverse rounds with cond(Jl) ε, and cond(Jl) ≤ π/2 for θ ≤ π (|Jl| ≤ 1, |Jl⁻¹| ≤ π/2).
    EXPECT_TRUE(
        matricesNear(leftJacobianInvSO3(phi), Mat3L(Jl.inverse()), kEvalUlps * kEps<S> * M_PI))
        << "phi " << phi.transpose();
    EXPECT_TRUE(
        matricesNear(rightJacobianInvSO3(phi), Mat3L(Jr.inverse()), kEvalUlps * kEps<S> * M_PI));
  }
}

TYPED_TEST(SO3Test, JacobianIdentities) {
  using S = TypeParam;
  const Mat3<S> I = Mat3<S>::Identity();
  for (const Vec3<S>& phi : hardRotationVectors<S>()) {
    const Mat3<S> Jl = leftJacobianSO3(phi);
    const Mat3<S> Jr = rightJacobianSO3(phi);
    EXPECT_TRUE(matricesNear(Jl * leftJacobianInvSO3(phi), I, kEvalUlps * kEps<S> * M_PI));
    EXPECT_TRUE(matricesNear(Jr * rightJacobianInvSO3(phi), I, kEvalUlps * kEps<S> * M_PI));
    EXPECT_TRUE(matricesNear(Jr, leftJacobianSO3<S>(-phi), 0.0));
    EXPECT_TRUE(matricesNear(Jl, expSO3(phi) * Jr, kEvalUlps * kEps<S>));
  }
}

// exp(φ + δ) ≈ exp(φ) exp(Jr δ) ≈ exp(Jl δ) exp(φ) and the inverse relations for log, by central
// differences of the log of the relative rotation (|f| ≤ π, |f'''| = O(1)).
TYPED_TEST(SO3Test, JacobiansMatchCentralDifferences) {
  using S = TypeParam;
  const S tol = fdTolerance<S>(S(M_PI));
  const Vec3<S> zero = Vec3<S>::Zero();
  for (const Vec3<S>& phi : hardRotationVectors<S>()) {
    const Mat3<S> R = expSO3(phi);
    const Mat3<S> Jr_fd = fdJacobian<S, 3, 3>(
        [&](const Vec3<S>& d) { return logSO3<S>(R.transpose() * expSO3<S>(phi + d)); }, zero);
    const Mat3<S> Jl_fd = fdJacobian<S, 3, 3>(
        [&](const Vec3<S>& d) { return logSO3<S>(expSO3<S>(phi + d) * R.transpose()); }, zero);
    const Mat3<S> Jr_inv_fd =
        fdJacobian<S, 3, 3>([&](const Vec3<S>& d) { return logNear<S>(R * expSO3(d), phi); }, zero);
    const Mat3<S> Jl_inv_fd =
        fdJacobian<S, 3, 3>([&](const Vec3<S>& d) { return logNear<S>(expSO3(d) * R, phi); }, zero);
    EXPECT_TRUE(matricesNear(rightJacobianSO3(phi), Jr_fd, tol)) << "phi " << phi.transpose();
    EXPECT_TRUE(matricesNear(leftJacobianSO3(phi), Jl_fd, tol)) << "phi " << phi.transpose();
    EXPECT_TRUE(matricesNear(rightJacobianInvSO3(phi), Jr_inv_fd, tol))
        << "phi " << phi.transpose();
    EXPECT_TRUE(matricesNear(leftJacobianInvSO3(phi), Jl_inv_fd, tol)) << "phi " << phi.transpose();
  }
}

// The float kernels agree with the double kernels on the same (float) input to O(ε_f).
TEST(SO3FloatVsDouble, KernelsAgree) {
  const double tol = kEvalUlps * kEps<float> * M_PI;
  for (const Vec3<float>& phi : hardRotationVectors<float>()) {
    const Vec3<double> phi_d = phi.cast<double>();
    const Mat3<float> R = expSO3(phi);
    EXPECT_TRUE(matricesNear(R, expSO3(phi_d), tol));
    const Vec3<double> w_d = logSO3(Mat3<double>(R.cast<double>()));
    if (w_d.norm() < M_PI - 1e-3) {
      EXPECT_TRUE(matricesNear(logSO3(R), w_d, tol));
    }
    EXPECT_TRUE(matricesNear(leftJacobianSO3(phi), leftJacobianSO3(phi_d), tol));
    EXPECT_TRUE(matricesNear(rightJacobianSO3(phi), rightJacobianSO3(phi_d), tol));
    EXPECT_TRUE(matricesNear(leftJacobianInvSO3(phi), leftJacobianInvSO3(phi_d), tol));
    EXPECT_TRUE(matricesNear(rightJacobianInvSO3(phi), rightJacobianInvSO3(phi_d), tol));
  }
}

}  // namespace
}  // namespace marglab::test
