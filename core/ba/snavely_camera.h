#pragma once
// Snavely's camera of the BAL problems (Agarwal et al., "Bundle Adjustment in the Large", ECCV
// 2010) and the reprojection residual with its analytic Jacobians.
//
// Model. A camera is (R_c_w, t_c_w, f, k1, k2); the file stores R_c_w as an angle-axis vector ω,
// R_c_w = exp(ω^). A world point X projects as
//     P = R_c_w X + t_c_w                     (camera frame; the camera looks along −z)
//     p = −P_xy / P_z                         (normalized image plane, y up)
//     d = 1 + k1 ‖p‖² + k2 ‖p‖⁴               (radial distortion)
//     r = f d p − z                           (residual in pixels, z the observation)
// A point with P_z ≥ 0 is behind the camera. Like rootba (optimized_cost = ERROR) and Ceres, its
// residual is kept in the cost and the linearization as it is; it is only counted (in front =
// P_z < 0).
//
// Parameterization of the solver (rootba's): a camera increment ξ = (δt, δφ, δf, δk1, δk2) ∈ ℝ⁹
// acts on the left of the pose, R ← exp(δφ^) R, t ← exp(δφ^) t + δt, so that P ← exp(δφ^) P + δt
// and, to first order, δP = δt − P^ δφ; the intrinsics are additive. Points are additive in the
// world frame.
//
// Jacobians (chain rule, u = ‖p‖²):
//     ∂p/∂P = −(1/P_z) [ I₂ | p ]                          (2×3)
//     ∂r/∂p = f (d I₂ + 2 (k1 + 2 k2 u) p pᵀ)              (2×2)
//     ∂r/∂ξ = [ ∂r/∂P · [ I₃ | −P^ ] | d p | f u p | f u² p ]
//     ∂r/∂X = ∂r/∂P · R
// with ∂r/∂P = ∂r/∂p · ∂p/∂P. With respect to the stored angle-axis ω (t fixed), as Ceres'
// autodiff of the same residual sees it: exp((ω + δω)^) ≈ exp((J_l(ω) δω)^) exp(ω^), so
//     ∂r/∂ω = −∂r/∂P · (P − t)^ · J_l(ω)
// (core/geometry/so3.h; the tests check both forms).

#include "core/common/eigen_types.h"

namespace marglab {

template <typename Scalar>
struct SnavelyCamera {
  Mat3<Scalar> R_c_w = Mat3<Scalar>::Identity();
  Vec3<Scalar> t_c_w = Vec3<Scalar>::Zero();
  Scalar f = 1;
  Scalar k1 = 0;
  Scalar k2 = 0;

  // From / to the 9 numbers of a BAL file (ω, t, f, k1, k2); toBal returns ω with |ω| ≤ π.
  static SnavelyCamera fromBal(const Vec<double, 9>& params);
  Vec<double, 9> toBal() const;
  // The increment ξ = (δt, δφ, δf, δk1, δk2) applied as documented above.
  void applyIncrement(const Vec<Scalar, 9>& xi);
  template <typename Other>
  SnavelyCamera<Other> cast() const {
    return {R_c_w.template cast<Other>(), t_c_w.template cast<Other>(), Other(f), Other(k1),
            Other(k2)};
  }
};

// The residual r of the observation z of X_w, and (when non-null) ∂r/∂ξ and ∂r/∂X. Returns true
// when the point is in front of the camera (P_z < 0). P_z = 0 gives non-finite values, which the
// caller's finiteness check reports.
template <typename Scalar>
bool snavelyResidual(const SnavelyCamera<Scalar>& camera, const Vec3<Scalar>& X_w,
                     const Vec<Scalar, 2>& z, Vec<Scalar, 2>* r,
                     Mat<Scalar, 2, 9>* J_camera = nullptr, Mat<Scalar, 2, 3>* J_point = nullptr);

}  // namespace marglab
