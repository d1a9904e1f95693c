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

#define MARGLAB_INST(S) template struct SnavelyCamera<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
