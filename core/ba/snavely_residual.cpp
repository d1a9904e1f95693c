// snavelyResidual (snavely_camera.h): compiled into the library and per ISA (core/isa_kernels.cmake)
// for the linearization of landmark_system.cpp.
#include "core/ba/snavely_camera.h"
#include "core/common/scalar.h"
#include "core/geometry/so3.h"

namespace marglab {

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
  template bool snavelyResidual<S>(const SnavelyCamera<S>&, const Vec3<S>&, const Vec<S, 2>&, \
                                   Vec<S, 2>*, Mat<S, 2, 9>*, Mat<S, 2, 3>*);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
