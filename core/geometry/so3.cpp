#include "core/geometry/so3.h"

namespace marglab {

template <typename Scalar>
Mat3<Scalar> leftJacobianSO3(const Vec3<Scalar>& phi) {
  const Scalar theta_sq = phi.squaredNorm();
  const Scalar theta = std::sqrt(theta_sq);
  const Mat3<Scalar> Phi = hat(phi);
  return Mat3<Scalar>::Identity() + so3_detail::coeffB(theta, theta_sq) * Phi +
         so3_detail::coeffC(theta, theta_sq) * (Phi * Phi);
}

template <typename Scalar>
Mat3<Scalar> leftJacobianInvSO3(const Vec3<Scalar>& phi) {
  const Scalar theta_sq = phi.squaredNorm();
  const Scalar theta = std::sqrt(theta_sq);
  const Mat3<Scalar> Phi = hat(phi);
  return Mat3<Scalar>::Identity() - Scalar(0.5) * Phi +
         so3_detail::coeffD(theta, theta_sq) * (Phi * Phi);
}

template <typename Scalar>
Mat3<Scalar> rightJacobianSO3(const Vec3<Scalar>& phi) {
  return leftJacobianSO3<Scalar>(-phi);
}

template <typename Scalar>
Mat3<Scalar> rightJacobianInvSO3(const Vec3<Scalar>& phi) {
  return leftJacobianInvSO3<Scalar>(-phi);
}

#define MARGLAB_INST(S)                                       \
  template Mat3<S> leftJacobianSO3<S>(const Vec3<S>& phi);    \
  template Mat3<S> leftJacobianInvSO3<S>(const Vec3<S>& phi); \
  template Mat3<S> rightJacobianSO3<S>(const Vec3<S>& phi);   \
  template Mat3<S> rightJacobianInvSO3<S>(const Vec3<S>& phi);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
