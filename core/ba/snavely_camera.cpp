#include "core/ba/snavely_camera.h"

#include "core/common/scalar.h"
#include "core/geometry/so3.h"

namespace marglab {

template <typename Scalar>
SnavelyCamera<Scalar> SnavelyCamera<Scalar>::fromBal(const Vec<double, 9>& params) {
  // Rodrigues in double whatever Scalar is: the file's digits, rounded once.
  const Mat3<double> R = expSO3<double>(params.head<3>());
  return {R.cast<Scalar>(), params.segment<3>(3).cast<Scalar>(), Scalar(params[6]),
          Scalar(params[7]), Scalar(params[8])};
}

template <typename Scalar>
Vec<double, 9> SnavelyCamera<Scalar>::toBal() const {
  Vec<double, 9> params;
  params << logSO3<double>(R_c_w.template cast<double>()), t_c_w.template cast<double>(), double(f),
      double(k1), double(k2);
  return params;
}

template <typename Scalar>
void SnavelyCamera<Scalar>::applyIncrement(const Vec<Scalar, 9>& xi) {
  const Mat3<Scalar> dR = expSO3<Scalar>(xi.template segment<3>(3));
  R_c_w = dR * R_c_w;
  t_c_w = dR * t_c_w + xi.template head<3>();
  f += xi[6];
  k1 += xi[7];
  k2 += xi[8];
}

template <typename Scalar>
bool snavelyResidual(const SnavelyCamera<Scalar>& camera, const Vec3<Scalar>& X_w,
                     const Vec<Scalar, 2>& z, Vec<Scalar, 2>* r, Mat<Scalar, 2, 9>* J_camera,
                     Mat<Scalar, 2, 3>* J_point) {
  const Vec3<Scalar> P = camera.R_c_w * X_w + camera.t_c_w;
  const Scalar inv_z = Scalar(1) / P.z();
  const Vec<Scalar, 2> p = -P.template head<2>() * inv_z;
  const Scalar u = p.squaredNorm();
  const Scalar d = Scalar(1) + u * (camera.k1 + u * camera.k2);
  *r = camera.f * d * p - z;
  if (J_camera == nullptr && J_point == nullptr) return P.z() < Scalar(0);

  Mat<Scalar, 2, 3> dp_dP;
  dp_dP << Scalar(1), Scalar(0), p.x(), Scalar(0), Scalar(1), p.y();
  dp_dP *= -inv_z;
  const Mat<Scalar, 2, 2> dr_dp =
      camera.f * (d * Mat<Scalar, 2, 2>::Identity() +
                  Scalar(2) * (camera.k1 + Scalar(2) * camera.k2 * u) * p * p.transpose());
  const Mat<Scalar, 2, 3> dr_dP = dr_dp * dp_dP;
  if (J_camera != nullptr) {
    J_camera->template leftCols<3>() = dr_dP;
    J_camera->template middleCols<3>(3) = -dr_dP * hat<Scalar>(P);
    J_camera->col(6) = d * p;
    J_camera->col(7) = camera.f * u * p;
    J_camera->col(8) = camera.f * u * u * p;
  }
  if (J_point != nullptr) *J_point = dr_dP * camera.R_c_w;
  return P.z() < Scalar(0);
}

#define MARGLAB_INST(S)                                                                       \
  template struct SnavelyCamera<S>;                                                           \
  template bool snavelyResidual<S>(const SnavelyCamera<S>&, const Vec3<S>&, const Vec<S, 2>&, \
                                   Vec<S, 2>*, Mat<S, 2, 9>*, Mat<S, 2, 3>*);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
