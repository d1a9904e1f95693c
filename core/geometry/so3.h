#pragma once
// SO(3): hat/vee, exponential and logarithm maps, left and right Jacobians and their inverses.
//
// Notation (Barfoot, "State Estimation for Robotics", 2017, §7.1; Sola et al., "A micro Lie
// theory for state estimation in robotics", 2018, appendix B). φ ∈ R³, θ = |φ|, Φ = φ^ = hat(φ):
//
//   hat(φ) = [  0  -φz  φy ]     vee(hat(φ)) = φ
//            [  φz  0  -φx ]
//            [ -φy  φx  0  ]
//
//   exp(φ)  = I + A Φ + B Φ²                          (Rodrigues)
//   Jl(φ)   = I + B Φ + C Φ²                          (Barfoot 7.77a)
//   Jl⁻¹(φ) = I − ½ Φ + D Φ²                          (Barfoot 7.77b)
//   Jr(φ)   = Jl(−φ) = I − B Φ + C Φ²,  Jr⁻¹(φ) = Jl⁻¹(−φ) = I + ½ Φ + D Φ²
//
// with the scalar coefficients
//   A = sin θ / θ,  B = (1 − cos θ)/θ² = 2 sin²(θ/2)/θ²,  C = (θ − sin θ)/θ³,
//   D = (1 − (θ/2) cot(θ/2))/θ²     (D → 1/π² at θ = π; singular only at θ = 2π).
//
// Jacobian conventions (first order in δ):
//   exp(φ + δ) ≈ exp(φ) · exp(Jr(φ) δ) ≈ exp(Jl(φ) δ) · exp(φ),   Jl(φ) = exp(φ) Jr(φ),
//   log(exp(φ) · exp(δ)) ≈ φ + Jr⁻¹(φ) δ,   log(exp(δ) · exp(φ)) ≈ φ + Jl⁻¹(φ) δ.
//
// Numerics. A and B are evaluated in forms free of cancellation (B through sin²(θ/2)); only θ → 0
// needs their Taylor series, used for θ² < √ε where the first omitted term is below ε. C and D
// lose relative accuracy ε/θ² when evaluated directly, but they multiply Φ² (norm θ²), so the
// matrices stay accurate to O(ε); they too switch to Taylor series for θ² < √ε. The series of C
// is also exposed with enough terms to be exact to double precision for θ ≤ 1, because the SE(3)
// Jacobians (se3.h) multiply it by terms that do not shrink with θ.
//
// logSO3 goes through the unit quaternion (Eigen's Shepperd-style conversion picks the largest
// diagonal element, so the axis is accurate near θ = π) and θ = 2 atan2(|q_v|, q_w), which is
// well conditioned at both ends: near θ = 0 the result is (2/q_w)(1 − |q_v|²/(3 q_w²)) q_v and
// near θ = π the atan2 never divides by a vanishing sine. The result has θ ∈ [0, π].

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "core/common/eigen_types.h"
#include "core/common/scalar.h"

namespace marglab {

namespace so3_detail {

// θ² below which the Taylor series of A, B, C, D (three terms) are used: the first omitted term
// is O(θ⁶) = O(ε^1.5), below the rounding of the closed forms.
template <typename Scalar>
inline Scalar taylorThetaSq() {
  return NumericTraits<Scalar>::sqrtEpsilon();
}

// A = sin θ / θ.
template <typename Scalar>
inline Scalar coeffA(Scalar theta, Scalar theta_sq) {
  if (theta_sq < taylorThetaSq<Scalar>()) {
    return Scalar(1) - theta_sq / Scalar(6) + theta_sq * theta_sq / Scalar(120);
  }
  return std::sin(theta) / theta;
}

// B = (1 − cos θ)/θ², evaluated as 2 sin²(θ/2)/θ² (no cancellation).
template <typename Scalar>
inline Scalar coeffB(Scalar theta, Scalar theta_sq) {
  if (theta_sq < taylorThetaSq<Scalar>()) {
    return Scalar(0.5) - theta_sq / Scalar(24) + theta_sq * theta_sq / Scalar(720);
  }
  const Scalar s = std::sin(Scalar(0.5) * theta);
  return Scalar(2) * s * s / theta_sq;
}

// C = (θ − sin θ)/θ³. For θ² < 1 the alternating series Σ (−1)^k θ^{2k}/(2k+3)!, truncated after
// the θ¹⁴ term (next term < 1e-17 relative): accurate to double precision with no cancellation.
template <typename Scalar>
inline Scalar coeffC(Scalar theta, Scalar theta_sq) {
  if (theta_sq < Scalar(1)) {
    const Scalar x = theta_sq;
    return Scalar(1.0 / 6.0) +
           x * (Scalar(-1.0 / 120.0) +
                x * (Scalar(1.0 / 5040.0) +
                     x * (Scalar(-1.0 / 362880.0) +
                          x * (Scalar(1.0 / 39916800.0) +
                               x * (Scalar(-1.0 / 6227020800.0) +
                                    x * (Scalar(1.0 / 1307674368000.0) +
                                         x * Scalar(-1.0 / 355687428096000.0)))))));
  }
  return (theta - std::sin(theta)) / (theta_sq * theta);
}

// D = (1 − (θ/2) cot(θ/2))/θ² = Σ |B_2n| θ^{2n−2}/(2n)!  (Bernoulli numbers).
template <typename Scalar>
inline Scalar coeffD(Scalar theta, Scalar theta_sq) {
  if (theta_sq < taylorThetaSq<Scalar>()) {
    return Scalar(1.0 / 12.0) + theta_sq / Scalar(720) + theta_sq * theta_sq / Scalar(30240);
  }
  const Scalar half = Scalar(0.5) * theta;
  return (Scalar(1) - half * std::cos(half) / std::sin(half)) / theta_sq;
}

}  // namespace so3_detail

// φ^ : the skew-symmetric matrix with φ^ a = φ × a.
template <typename Scalar>
inline Mat3<Scalar> hat(const Vec3<Scalar>& phi) {
  Mat3<Scalar> Phi;
  Phi << Scalar(0), -phi.z(), phi.y(), phi.z(), Scalar(0), -phi.x(), -phi.y(), phi.x(), Scalar(0);
  return Phi;
}

// Inverse of hat; reads the antisymmetric part (exact for a skew matrix).
template <typename Scalar>
inline Vec3<Scalar> vee(const Mat3<Scalar>& Phi) {
  return Vec3<Scalar>(Scalar(0.5) * (Phi(2, 1) - Phi(1, 2)), Scalar(0.5) * (Phi(0, 2) - Phi(2, 0)),
                      Scalar(0.5) * (Phi(1, 0) - Phi(0, 1)));
}

// Rodrigues: exp(φ) = I + A Φ + B Φ².
template <typename Scalar>
inline Mat3<Scalar> expSO3(const Vec3<Scalar>& phi) {
  const Scalar theta_sq = phi.squaredNorm();
  const Scalar theta = std::sqrt(theta_sq);
  const Mat3<Scalar> Phi = hat(phi);
  return Mat3<Scalar>::Identity() + so3_detail::coeffA(theta, theta_sq) * Phi +
         so3_detail::coeffB(theta, theta_sq) * (Phi * Phi);
}

// exp(φ) as a unit quaternion: q = (cos(θ/2), sin(θ/2)/θ · φ).
template <typename Scalar>
inline Eigen::Quaternion<Scalar> expSO3Quaternion(const Vec3<Scalar>& phi) {
  const Scalar theta_sq = phi.squaredNorm();
  const Scalar theta = std::sqrt(theta_sq);
  const Scalar half = Scalar(0.5) * theta;
  // sin(θ/2)/θ = ½ A(θ/2).
  const Scalar k = Scalar(0.5) * so3_detail::coeffA(half, Scalar(0.25) * theta_sq);
  return Eigen::Quaternion<Scalar>(std::cos(half), k * phi.x(), k * phi.y(), k * phi.z());
}

// Logarithm of a unit quaternion, θ ∈ [0, π] (the sign of q is chosen with q_w ≥ 0).
template <typename Scalar>
inline Vec3<Scalar> logSO3(const Eigen::Quaternion<Scalar>& q_in) {
  Eigen::Quaternion<Scalar> q = q_in;
  if (q.w() < Scalar(0)) q.coeffs() = -q.coeffs();
  const Vec3<Scalar> v = q.vec();
  const Scalar n_sq = v.squaredNorm();
  const Scalar w = q.w();
  // Series branch: |q_v| ≤ ε^{1/4} ⇒ θ ≲ 2 ε^{1/4}; first omitted term O(n⁴) is below ε.
  if (n_sq < NumericTraits<Scalar>::sqrtEpsilon() * w * w) {
    return (Scalar(2) / w) * (Scalar(1) - n_sq / (Scalar(3) * w * w)) * v;
  }
  const Scalar n = std::sqrt(n_sq);
  return (Scalar(2) * std::atan2(n, w) / n) * v;
}

// Logarithm of a rotation matrix, θ ∈ [0, π]. R is assumed orthonormal to working precision.
template <typename Scalar>
inline Vec3<Scalar> logSO3(const Mat3<Scalar>& R) {
  return logSO3(Eigen::Quaternion<Scalar>(R));
}

// Jacobians (declared here, defined in so3.cpp, instantiated for float and double).
template <typename Scalar>
Mat3<Scalar> leftJacobianSO3(const Vec3<Scalar>& phi);
template <typename Scalar>
Mat3<Scalar> leftJacobianInvSO3(const Vec3<Scalar>& phi);
template <typename Scalar>
Mat3<Scalar> rightJacobianSO3(const Vec3<Scalar>& phi);
template <typename Scalar>
Mat3<Scalar> rightJacobianInvSO3(const Vec3<Scalar>& phi);

}  // namespace marglab
