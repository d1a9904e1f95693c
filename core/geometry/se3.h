#pragma once
// SE(3): rigid transforms, exponential/logarithm, and the estimator's pose increment ⊞ / ⊟.
//
// Representation. SE3<Scalar> stores a unit quaternion q (rotation R) and a translation t, and
// acts as T · p = R p + t. A quaternion is renormalized cheaply after every composition and
// increment, so repeated updates in float stay on the manifold (a 3×3 matrix would drift from
// orthonormality). Frames are named as in Sophus/Basalt: T_a_b maps points from frame b to a.
//
// Tangent ordering: ξ = [υ; ω] ∈ R⁶, translation part first, rotation part second (Barfoot,
// "State Estimation for Robotics", §7.1.3; the same order as the ⊞ increment below).
//   exp(ξ) = ( exp(ω), Jl(ω) υ )                    Jl = left Jacobian of SO(3), see so3.h
//   log(T) = [ Jl⁻¹(ω) t ; ω ],  ω = log(R)
//
// Estimator increment (docs/design.md §3): δ = [δt; δφ], translation additive, rotation
// left-multiplied (perturbation in the world frame, not the SE(3) exponential):
//   T ⊞ δ = ( exp(δφ) R, t + δt ),      T_a ⊟ T_b = [ t_a − t_b ; log(R_a R_bᵀ) ],
// so that T_b ⊞ (T_a ⊟ T_b) = T_a. Every pose Jacobian in the project is w.r.t. this δ.
//
// relativePose computes T_ct_ch = (T_w_it T_i_ct)⁻¹ (T_w_ih T_i_ch) — the transform from the host
// camera to the target camera given body poses and body-to-camera extrinsics — with its
// Jacobians w.r.t. ⊞ increments of T_w_ih and T_w_it, expressed as ⊞ increments of T_ct_ch.
// With M = R_ct_w:
//   ∂/∂δ_h = [ M  −M [R_w_ih t_i_ch]× ],     ∂/∂δ_t = [ −M  M [t_w_ch − t_w_it]× ]
//            [ 0   M                 ]                [  0  −M                  ]

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/common/eigen_types.h"
#include "core/geometry/so3.h"

namespace marglab {

template <typename Scalar>
class SE3 {
 public:
  SE3() : q_(Eigen::Quaternion<Scalar>::Identity()), t_(Vec3<Scalar>::Zero()) {}
  // q is normalized on construction.
  SE3(const Eigen::Quaternion<Scalar>& q, const Vec3<Scalar>& t) : q_(q.normalized()), t_(t) {}
  // R must be a rotation matrix (converted to a unit quaternion).
  SE3(const Mat3<Scalar>& R, const Vec3<Scalar>& t) : q_(Eigen::Quaternion<Scalar>(R)), t_(t) {
    q_.normalize();
  }

  // exp([υ; ω]) = (exp(ω), Jl(ω) υ).
  static SE3 exp(const Vec<Scalar, 6>& xi) {
    const Vec3<Scalar> omega = xi.template tail<3>();
    return SE3(expSO3Quaternion(omega), leftJacobianSO3(omega) * xi.template head<3>());
  }

  // log(T) = [Jl⁻¹(ω) t; ω] with ω = log(R), θ ∈ [0, π].
  Vec<Scalar, 6> log() const {
    Vec<Scalar, 6> xi;
    const Vec3<Scalar> omega = logSO3(q_);
    xi.template head<3>() = leftJacobianInvSO3(omega) * t_;
    xi.template tail<3>() = omega;
    return xi;
  }

  const Eigen::Quaternion<Scalar>& unitQuaternion() const { return q_; }
  Mat3<Scalar> rotationMatrix() const { return q_.toRotationMatrix(); }
  const Vec3<Scalar>& translation() const { return t_; }
  Vec3<Scalar>& translation() { return t_; }

  SE3 operator*(const SE3& other) const { return SE3(q_ * other.q_, t_ + q_ * other.t_); }
  Vec3<Scalar> operator*(const Vec3<Scalar>& p) const { return q_ * p + t_; }
  SE3 inverse() const {
    const Eigen::Quaternion<Scalar> q_inv = q_.conjugate();
    return SE3(q_inv, -(q_inv * t_));
  }

  Mat<Scalar, 4, 4> matrix() const {
    Mat<Scalar, 4, 4> M = Mat<Scalar, 4, 4>::Identity();
    M.template topLeftCorner<3, 3>() = rotationMatrix();
    M.template topRightCorner<3, 1>() = t_;
    return M;
  }

  template <typename T>
  SE3<T> cast() const {
    return SE3<T>(q_.template cast<T>(), t_.template cast<T>());
  }

 private:
  Eigen::Quaternion<Scalar> q_;
  Vec3<Scalar> t_;
};

using SE3f = SE3<float>;
using SE3d = SE3<double>;

// T ⊞ δ = (exp(δφ) R, t + δt), δ = [δt; δφ].
template <typename Scalar>
inline SE3<Scalar> boxPlus(const SE3<Scalar>& T, const Vec<Scalar, 6>& delta) {
  return SE3<Scalar>(expSO3Quaternion<Scalar>(delta.template tail<3>()) * T.unitQuaternion(),
                     T.translation() + delta.template head<3>());
}

// T_a ⊟ T_b = [t_a − t_b; log(R_a R_bᵀ)], the δ with T_b ⊞ δ = T_a.
template <typename Scalar>
inline Vec<Scalar, 6> boxMinus(const SE3<Scalar>& T_a, const SE3<Scalar>& T_b) {
  Vec<Scalar, 6> delta;
  delta.template head<3>() = T_a.translation() - T_b.translation();
  delta.template tail<3>() =
      logSO3<Scalar>(T_a.unitQuaternion() * T_b.unitQuaternion().conjugate());
  return delta;
}

// T_ct_ch = (T_w_it T_i_ct)⁻¹ T_w_ih T_i_ch and its ⊞ Jacobians w.r.t. T_w_ih and T_w_it
// (either Jacobian pointer may be null).
template <typename Scalar>
SE3<Scalar> relativePose(const SE3<Scalar>& T_w_ih, const SE3<Scalar>& T_i_ch,
                         const SE3<Scalar>& T_w_it, const SE3<Scalar>& T_i_ct,
                         Mat<Scalar, 6, 6>* d_rel_d_h = nullptr,
                         Mat<Scalar, 6, 6>* d_rel_d_t = nullptr);

// Without extrinsics: T_t_h = T_w_t⁻¹ T_w_h.
template <typename Scalar>
inline SE3<Scalar> relativePose(const SE3<Scalar>& T_w_h, const SE3<Scalar>& T_w_t,
                                Mat<Scalar, 6, 6>* d_rel_d_h = nullptr,
                                Mat<Scalar, 6, 6>* d_rel_d_t = nullptr) {
  return relativePose(T_w_h, SE3<Scalar>(), T_w_t, SE3<Scalar>(), d_rel_d_h, d_rel_d_t);
}

}  // namespace marglab
