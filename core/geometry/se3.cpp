#include "core/geometry/se3.h"

namespace marglab {

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

#define MARGLAB_INST(S)                                                       \
  template SE3<S> relativePose<S>(const SE3<S>& T_w_ih, const SE3<S>& T_i_ch, \
                                  const SE3<S>& T_w_it, const SE3<S>& T_i_ct, \
                                  Mat<S, 6, 6>* d_rel_d_h, Mat<S, 6, 6>* d_rel_d_t);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
