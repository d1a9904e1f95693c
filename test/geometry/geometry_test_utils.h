#pragma once
// Shared helpers of the geometry tests: scalar type list, central differences with their error
// bound, and the "hard" rotation vectors (θ = 0, tiny, near π, random).
//
// Central differences. For f evaluated with relative rounding error ≤ k ε |f| and step h,
//   |(f(x+h) − f(x−h))/(2h) − f'(x)| ≤ h² |f'''|/6 + k ε |f| / h,
// minimized near h = ε^{1/3}, where the bound is ε^{2/3} (|f'''|/6 + k |f|). The tests pass the
// magnitudes of f and f''' of the function at hand (O(1) for the inputs used here) and use
// k = kEvalUlps, the rounding of a geometry kernel of a few dozen flops.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/common/scalar.h"

namespace marglab::test {

using ScalarTypes = ::testing::Types<float, double>;

struct ScalarNames {
  template <typename T>
  static std::string GetName(int) {
    return std::string(NumericTraits<T>::name());
  }
};

template <typename Scalar>
constexpr Scalar kEps = std::numeric_limits<Scalar>::epsilon();

// Rounding error of one evaluation of a geometry kernel, in units of ε·|f|.
constexpr double kEvalUlps = 8.0;

template <typename Scalar>
Scalar fdStep() {
  return std::cbrt(kEps<Scalar>);
}

// Error bound of fdJacobian for |f| ≤ f_scale and |f'''| ≤ d3_scale.
template <typename Scalar>
Scalar fdTolerance(Scalar f_scale = Scalar(1), Scalar d3_scale = Scalar(1)) {
  const Scalar h = fdStep<Scalar>();
  return h * h * d3_scale / Scalar(6) + Scalar(kEvalUlps) * kEps<Scalar> * f_scale / h;
}

// Central-difference Jacobian of f : R^N → R^M at x, step h·max(1, |x_i|).
template <typename Scalar, int M, int N, typename F>
Mat<Scalar, M, N> fdJacobian(const F& f, const Vec<Scalar, N>& x) {
  Mat<Scalar, M, N> J;
  for (int i = 0; i < N; ++i) {
    const Scalar h = fdStep<Scalar>() * std::max(Scalar(1), std::abs(x[i]));
    Vec<Scalar, N> xp = x;
    Vec<Scalar, N> xm = x;
    xp[i] += h;
    xm[i] -= h;
    J.col(i) = (f(xp) - f(xm)) / (xp[i] - xm[i]);
  }
  return J;
}

template <typename Derived1, typename Derived2>
::testing::AssertionResult matricesNear(const Eigen::MatrixBase<Derived1>& a,
                                        const Eigen::MatrixBase<Derived2>& b, double tol) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) {
    return ::testing::AssertionFailure() << "size mismatch";
  }
  const double err = (a.template cast<double>() - b.template cast<double>()).cwiseAbs().maxCoeff();
  if (std::isfinite(err) && err <= tol) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "max |a − b| = " << err << " > tol " << tol << "\na =\n"
                                       << a << "\nb =\n"
                                       << b;
}

// Gap to π of the "near π" test angle: π − 1e-6 in double; in float 1e-5 (≈ 40 ulps of π), since
// float cannot resolve rotations closer to π than a few ulps.
template <typename Scalar>
Scalar nearPiGap() {
  return std::is_same_v<Scalar, double> ? Scalar(1e-6) : Scalar(1e-5);
}

// "Tiny" angle: 1e-8 in double, 1e-4 in float.
template <typename Scalar>
Scalar tinyAngle() {
  return std::is_same_v<Scalar, double> ? Scalar(1e-8) : Scalar(1e-4);
}

template <typename Scalar>
Vec3<Scalar> randomUnit(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Vector3d v(n(rng), n(rng), n(rng));
  return v.normalized().cast<Scalar>();
}

// Rotation vectors with θ = 0, tiny, 1e-3, 0.5, 1 (the series/closed-form switch of C, E, F),
// π − gap, π, and 16 random ones with θ uniform in (0, π).
template <typename Scalar>
std::vector<Vec3<Scalar>> hardRotationVectors(unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::vector<Vec3<Scalar>> out;
  const double pi = M_PI;
  out.push_back(Vec3<Scalar>::Zero());
  for (double theta :
       {double(tinyAngle<Scalar>()), 1e-3, 0.5, 1.0, pi - double(nearPiGap<Scalar>()), pi}) {
    out.push_back((randomUnit<double>(rng) * theta).template cast<Scalar>());
  }
  std::uniform_real_distribution<double> angle(0.0, pi);
  for (int i = 0; i < 16; ++i) {
    out.push_back((randomUnit<double>(rng) * angle(rng)).template cast<Scalar>());
  }
  return out;
}

}  // namespace marglab::test
