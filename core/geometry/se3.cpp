#include "core/geometry/se3.h"

namespace marglab {
namespace {

// E = (θ² + 2 cos θ − 2)/(2θ⁴) = Σ_j (−1)^j θ^{2j}/(2j+4)!; the series (to θ¹⁶, next term
// < 1e-17 relative) is used for θ² < 1, where the closed form cancels.
template <typename Scalar>
Scalar coeffE(Scalar theta, Scalar theta_sq) {
  if (theta_sq < Scalar(1)) {
    const Scalar x = theta_sq;
    return Scalar(1.0 / 24.0) +
           x * (Scalar(-1.0 / 720.0) +
                x * (Scalar(1.0 / 40320.0) +
                     x * (Scalar(-1.0 / 3628800.0) +
                          x * (Scalar(1.0 / 479001600.0) +
                               x * (Scalar(-1.0 / 87178291200.0) +
                                    x * (Scalar(1.0 / 20922789888000.0) +
                                         x * (Scalar(-1.0 / 6402373705728000.0) +
                                              x * Scalar(1.0 / 2432902008176640000.0))))))));
  }
  return (theta_sq + Scalar(2) * std::cos(theta) - Scalar(2)) / (Scalar(2) * theta_sq * theta_sq);
}

// F = (2θ − 3 sin θ + θ cos θ)/(2θ⁵) = Σ_j (−1)^j (j+1) θ^{2j}/(2j+5)!; series for θ² < 1.
template <typename Scalar>
Scalar coeffF(Scalar theta, Scalar theta_sq) {
  if (theta_sq < Scalar(1)) {
    const Scalar x = theta_sq;
    return Scalar(1.0 / 120.0) +
           x * (Scalar(-2.0 / 5040.0) +
                x * (Scalar(3.0 / 362880.0) +
                     x * (Scalar(-4.0 / 39916800.0) +
                          x * (Scalar(5.0 / 6227020800.0) +
                               x * (Scalar(-6.0 / 1307674368000.0) +
                                    x * (Scalar(7.0 / 355687428096000.0) +
                                         x * (Scalar(-8.0 / 121645100408832000.0) +
                                              x * Scalar(9.0 / 51090942171709440000.0))))))));
  }
  return (Scalar(2) * theta - Scalar(3) * std::sin(theta) + theta * std::cos(theta)) /
         (Scalar(2) * theta_sq * theta_sq * theta);
}

}  // namespace

template <typename Scalar>
Mat3<Scalar> leftJacobianQBlockSE3(const Vec3<Scalar>& upsilon, const Vec3<Scalar>& omega) {
  const Scalar theta_sq = omega.squaredNorm();
  const Scalar theta = std::sqrt(theta_sq);
  const Mat3<Scalar> W = hat(omega);
  const Mat3<Scalar> U = hat(upsilon);
  const Mat3<Scalar> WU = W * U;
  const Mat3<Scalar> UW = U * W;
  const Mat3<Scalar> WUW = WU * W;
  const Mat3<Scalar> WWU = W * WU;
  const Mat3<Scalar> UWW = UW * W;
  return Scalar(0.5) * U + so3_detail::coeffC(theta, theta_sq) * (WU + UW + WUW) +
         coeffE(theta, theta_sq) * (WWU + UWW - Scalar(3) * WUW) +
         coeffF(theta, theta_sq) * (WUW * W + W * WUW);
}

template <typename Scalar>
Mat<Scalar, 6, 6> leftJacobianSE3(const Vec<Scalar, 6>& xi) {
  const Vec3<Scalar> upsilon = xi.template head<3>();
  const Vec3<Scalar> omega = xi.template tail<3>();
  const Mat3<Scalar> Jl = leftJacobianSO3(omega);
  Mat<Scalar, 6, 6> J;
  J.template topLeftCorner<3, 3>() = Jl;
  J.template topRightCorner<3, 3>() = leftJacobianQBlockSE3(upsilon, omega);
  J.template bottomLeftCorner<3, 3>().setZero();
  J.template bottomRightCorner<3, 3>() = Jl;
  return J;
}

template <typename Scalar>
Mat<Scalar, 6, 6> leftJacobianInvSE3(const Vec<Scalar, 6>& xi) {
  const Vec3<Scalar> upsilon = xi.template head<3>();
  const Vec3<Scalar> omega = xi.template tail<3>();
  const Mat3<Scalar> Jl_inv = leftJacobianInvSO3(omega);
  Mat<Scalar, 6, 6> J;
  J.template topLeftCorner<3, 3>() = Jl_inv;
  J.template topRightCorner<3, 3>() = -Jl_inv * leftJacobianQBlockSE3(upsilon, omega) * Jl_inv;
  J.template bottomLeftCorner<3, 3>().setZero();
  J.template bottomRightCorner<3, 3>() = Jl_inv;
  return J;
}

template <typename Scalar>
Mat<Scalar, 6, 6> rightJacobianSE3(const Vec<Scalar, 6>& xi) {
  return leftJacobianSE3<Scalar>(-xi);
}

template <typename Scalar>
Mat<Scalar, 6, 6> rightJacobianInvSE3(const Vec<Scalar, 6>& xi) {
  return leftJacobianInvSE3<Scalar>(-xi);
}

template <typename Scalar>
SE3<Scalar> relativePose(const SE3<Scalar>& T_w_ih, const SE3<Scalar>& T_i_ch,
                         const SE3<Scalar>& T_w_it, const SE3<Scalar>& T_i_ct,
                         Mat<Scalar, 6, 6>* d_rel_d_h, Mat<Scalar, 6, 6>* d_rel_d_t) {
  const SE3<Scalar> T_ct_w = (T_w_it * T_i_ct).inverse();
  const SE3<Scalar> T_w_ch = T_w_ih * T_i_ch;
  if (d_rel_d_h != nullptr || d_rel_d_t != nullptr) {
    const Mat3<Scalar> M = T_ct_w.rotationMatrix();
    if (d_rel_d_h != nullptr) {
      d_rel_d_h->template topLeftCorner<3, 3>() = M;
      d_rel_d_h->template topRightCorner<3, 3>() =
          -M * hat<Scalar>(T_w_ih.unitQuaternion() * T_i_ch.translation());
      d_rel_d_h->template bottomLeftCorner<3, 3>().setZero();
      d_rel_d_h->template bottomRightCorner<3, 3>() = M;
    }
    if (d_rel_d_t != nullptr) {
      d_rel_d_t->template topLeftCorner<3, 3>() = -M;
      d_rel_d_t->template topRightCorner<3, 3>() =
          M * hat<Scalar>(T_w_ch.translation() - T_w_it.translation());
      d_rel_d_t->template bottomLeftCorner<3, 3>().setZero();
      d_rel_d_t->template bottomRightCorner<3, 3>() = -M;
    }
  }
  return T_ct_w * T_w_ch;
}

#define MARGLAB_INST(S)                                                                    \
  template Mat3<S> leftJacobianQBlockSE3<S>(const Vec3<S>& upsilon, const Vec3<S>& omega); \
  template Mat<S, 6, 6> leftJacobianSE3<S>(const Vec<S, 6>& xi);                           \
  template Mat<S, 6, 6> leftJacobianInvSE3<S>(const Vec<S, 6>& xi);                        \
  template Mat<S, 6, 6> rightJacobianSE3<S>(const Vec<S, 6>& xi);                          \
  template Mat<S, 6, 6> rightJacobianInvSE3<S>(const Vec<S, 6>& xi);                       \
  template SE3<S> relativePose<S>(const SE3<S>& T_w_ih, const SE3<S>& T_i_ch,              \
                                  const SE3<S>& T_w_it, const SE3<S>& T_i_ct,              \
                                  Mat<S, 6, 6>* d_rel_d_h, Mat<S, 6, 6>* d_rel_d_t);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
