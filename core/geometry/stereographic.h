#pragma once
// Landmark parameterization (Basalt, Usenko et al. 2019; Demmel et al. ICCV 2021 §3): a 2-dof
// stereographic bearing (u, v) plus inverse distance ρ in the host camera, ℓ = (u, v, ρ).
//
// Stereographic projection from the pole (0, 0, −1) of the unit sphere onto the plane z = 0:
//   u = x / (1 + z),  v = y / (1 + z)                                 for a unit bearing b,
//   b(u, v) = (2u, 2v, 1 − u² − v²) / (1 + u² + v²)                   (inverse, always |b| = 1).
// The forward camera axis (0, 0, 1) maps to (0, 0); the map is smooth everywhere except at the
// pole (0, 0, −1), i.e. for bearings pointing backwards, which hosted landmarks never have.
//
// stereographicProject accepts any nonzero p and uses u = x / (|p| + z) (as Basalt), which equals
// the above for |p| = 1 and is invariant to the scale of p; its 2×3 Jacobian therefore has p in
// its nullspace. For z < 0 the denominator is evaluated as (x² + y²)/(|p| − z) to avoid the
// cancellation in |p| + z. Jacobians (n = 1 + u² + v², m = |p| + z, s = |p|):
//   ∂u/∂p = e_xᵀ/m − x/m² (p/s + e_z)ᵀ,   ∂v/∂p = e_yᵀ/m − y/m² (p/s + e_z)ᵀ,
//   ∂b/∂(u,v) = (1/n²) [ 2n − 4u²   −4uv     ]
//                      [ −4uv       2n − 4v² ]
//                      [ −4u        −4v      ]
//
// The landmark point in the host camera is p_h = b(u, v)/ρ, in homogeneous form [b; ρ]. In a
// target camera it is p_t = R_t_h p_h + t_t_h ∝ R_t_h b + t_t_h ρ (scaled by ρ > 0; a pinhole
// projection is invariant to that scale, and ρ = 0 is a point at infinity). transformLandmark
// returns this scaled point q = R_t_h b + ρ t_t_h with
//   ∂q/∂(u, v) = R_t_h ∂b/∂(u,v),   ∂q/∂ρ = t_t_h,
//   ∂q/∂δ = [ ρ I₃,  −[R_t_h b]× ]   for the ⊞ increment of T_t_h, δ = [δt; δφ] (se3.h):
// (exp(δφ) R, t + δt) moves q by ρ δt + δφ × (R b).
// Note: the depth of q is ρ times the metric depth, so a camera's minimum-depth test on q
// compares z_t / d_h (d_h = distance from the host camera) with the threshold.

#include <Eigen/Core>
#include <cmath>

#include "core/common/eigen_types.h"
#include "core/geometry/se3.h"
#include "core/geometry/so3.h"

namespace marglab {

// (u, v) of the direction of p (p ≠ 0, not along (0, 0, −1)).
template <typename Scalar>
inline Vec<Scalar, 2> stereographicProject(const Vec3<Scalar>& p,
                                           Mat<Scalar, 2, 3>* d_uv_d_p = nullptr) {
  const Scalar s = p.norm();
  const Scalar m = p.z() >= Scalar(0) ? s + p.z() : (p.x() * p.x() + p.y() * p.y()) / (s - p.z());
  const Scalar m_inv = Scalar(1) / m;
  const Vec<Scalar, 2> uv(p.x() * m_inv, p.y() * m_inv);
  if (d_uv_d_p != nullptr) {
    Vec3<Scalar> d_m_d_p = p / s;
    d_m_d_p.z() += Scalar(1);
    d_uv_d_p->row(0) = -uv.x() * m_inv * d_m_d_p.transpose();
    d_uv_d_p->row(1) = -uv.y() * m_inv * d_m_d_p.transpose();
    (*d_uv_d_p)(0, 0) += m_inv;
    (*d_uv_d_p)(1, 1) += m_inv;
  }
  return uv;
}

// Unit bearing b(u, v).
template <typename Scalar>
inline Vec3<Scalar> stereographicUnproject(const Vec<Scalar, 2>& uv,
                                           Mat<Scalar, 3, 2>* d_b_d_uv = nullptr) {
  const Scalar u = uv.x();
  const Scalar v = uv.y();
  const Scalar r_sq = u * u + v * v;
  const Scalar n = Scalar(1) + r_sq;
  const Scalar n_inv = Scalar(1) / n;
  if (d_b_d_uv != nullptr) {
    const Scalar n_inv_sq = n_inv * n_inv;
    (*d_b_d_uv) << (Scalar(2) * n - Scalar(4) * u * u) * n_inv_sq, Scalar(-4) * u * v * n_inv_sq,
        Scalar(-4) * u * v * n_inv_sq, (Scalar(2) * n - Scalar(4) * v * v) * n_inv_sq,
        Scalar(-4) * u * n_inv_sq, Scalar(-4) * v * n_inv_sq;
  }
  return Vec3<Scalar>(Scalar(2) * u * n_inv, Scalar(2) * v * n_inv, (Scalar(1) - r_sq) * n_inv);
}

// ℓ = (u, v, 1/|p_h|) of a point p_h ≠ 0 in the host camera.
template <typename Scalar>
inline Vec3<Scalar> landmarkFromPoint(const Vec3<Scalar>& p_h) {
  const Vec<Scalar, 2> uv = stereographicProject(p_h);
  return Vec3<Scalar>(uv.x(), uv.y(), Scalar(1) / p_h.norm());
}

// p_h = b(u, v)/ρ for ρ > 0.
template <typename Scalar>
inline Vec3<Scalar> landmarkToPoint(const Vec3<Scalar>& landmark) {
  return stereographicUnproject<Scalar>(landmark.template head<2>()) / landmark.z();
}

// q = R_t_h b(u, v) + ρ t_t_h (the target-camera point scaled by ρ) and its Jacobians w.r.t.
// ℓ = (u, v, ρ) and the ⊞ increment of T_t_h. Either Jacobian pointer may be null.
template <typename Scalar>
inline Vec3<Scalar> transformLandmark(const SE3<Scalar>& T_t_h, const Vec3<Scalar>& landmark,
                                      Mat<Scalar, 3, 3>* d_q_d_landmark = nullptr,
                                      Mat<Scalar, 3, 6>* d_q_d_T_t_h = nullptr) {
  Mat<Scalar, 3, 2> d_b_d_uv;
  const Vec3<Scalar> b = stereographicUnproject<Scalar>(
      landmark.template head<2>(), d_q_d_landmark != nullptr ? &d_b_d_uv : nullptr);
  const Scalar rho = landmark.z();
  const Mat3<Scalar> R = T_t_h.rotationMatrix();
  const Vec3<Scalar> Rb = R * b;
  if (d_q_d_landmark != nullptr) {
    d_q_d_landmark->template leftCols<2>() = R * d_b_d_uv;
    d_q_d_landmark->col(2) = T_t_h.translation();
  }
  if (d_q_d_T_t_h != nullptr) {
    d_q_d_T_t_h->template leftCols<3>() = rho * Mat3<Scalar>::Identity();
    d_q_d_T_t_h->template rightCols<3>() = -hat(Rb);
  }
  return Rb + rho * T_t_h.translation();
}

}  // namespace marglab
