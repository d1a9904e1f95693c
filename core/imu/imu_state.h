#pragma once
// The 15-dof VIO state of one frame and its increment (docs/design.md §3).
//
//   state  x = (T_w_i, v_w, b_g, b_a): pose of the IMU/body frame i in the world, velocity of the
//          body origin in the world frame, gyro bias [rad/s], accel bias [m/s²].
//   increment δ ∈ R¹⁵, ordered [δt (0..2); δφ (3..5); δv (6..8); δb_g (9..11); δb_a (12..14)]:
//     x ⊞ δ = (T_w_i ⊞ [δt; δφ], v_w + δv, b_g + δb_g, b_a + δb_a)
//   with the pose increment of se3.h: R ← exp(δφ) R (left, world-frame rotation perturbation),
//   t ← t + δt. ⊟ is its inverse: x_b ⊞ (x_a ⊟ x_b) = x_a.
// Every IMU Jacobian in core/imu is with respect to this δ, per state, in this column order.

#include <Eigen/Core>
#include <cstdint>

#include "core/common/eigen_types.h"
#include "core/geometry/se3.h"

namespace marglab {

// Column offsets of the blocks of the 15-dof state increment.
struct ImuStateIndex {
  static constexpr int kPos = 0;
  static constexpr int kRot = 3;
  static constexpr int kVel = 6;
  static constexpr int kBiasGyro = 9;
  static constexpr int kBiasAccel = 12;
  static constexpr int kDim = 15;
};

template <typename Scalar>
struct ImuState {
  int64_t t_ns = 0;
  SE3<Scalar> T_w_i;
  Vec3<Scalar> v_w = Vec3<Scalar>::Zero();
  Vec3<Scalar> b_g = Vec3<Scalar>::Zero();
  Vec3<Scalar> b_a = Vec3<Scalar>::Zero();

  template <typename T>
  ImuState<T> cast() const {
    ImuState<T> s;
    s.t_ns = t_ns;
    s.T_w_i = T_w_i.template cast<T>();
    s.v_w = v_w.template cast<T>();
    s.b_g = b_g.template cast<T>();
    s.b_a = b_a.template cast<T>();
    return s;
  }
};

template <typename Scalar>
inline ImuState<Scalar> boxPlus(const ImuState<Scalar>& x, const Vec<Scalar, 15>& delta) {
  ImuState<Scalar> out;
  out.t_ns = x.t_ns;
  out.T_w_i = boxPlus(x.T_w_i, Vec<Scalar, 6>(delta.template head<6>()));
  out.v_w = x.v_w + delta.template segment<3>(ImuStateIndex::kVel);
  out.b_g = x.b_g + delta.template segment<3>(ImuStateIndex::kBiasGyro);
  out.b_a = x.b_a + delta.template segment<3>(ImuStateIndex::kBiasAccel);
  return out;
}

template <typename Scalar>
inline Vec<Scalar, 15> boxMinus(const ImuState<Scalar>& x_a, const ImuState<Scalar>& x_b) {
  Vec<Scalar, 15> delta;
  delta.template head<6>() = boxMinus(x_a.T_w_i, x_b.T_w_i);
  delta.template segment<3>(ImuStateIndex::kVel) = x_a.v_w - x_b.v_w;
  delta.template segment<3>(ImuStateIndex::kBiasGyro) = x_a.b_g - x_b.b_g;
  delta.template segment<3>(ImuStateIndex::kBiasAccel) = x_a.b_a - x_b.b_a;
  return delta;
}

}  // namespace marglab
