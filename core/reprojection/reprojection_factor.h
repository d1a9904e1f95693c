#pragma once
// The reprojection factor of the estimator: one stereo observation z of a landmark in camera c of
// a target frame t, as the Huber-robustified, whitened residual rows
//     r = (√w / σ) (π_c(q) − z),   e = ‖π_c(q) − z‖,   w = 1 if e ≤ k else k / e,
// whose squared norm is the IRLS model of the Huber cost ρ_H(e)/σ² = (½e² | k e − ½k²)/σ²
// (threshold k = huber_px, σ = obs_std_px, docs/design.md §3). π_c is the pinhole projection of
// core/geometry/camera.h. Two landmark parametrizations give the point q in the target camera:
//
//   hosted  ℓ = (u, v, ρ) in the host's cam0 (stereographic bearing, inverse distance):
//           q = R_ct_h b(u, v) + ρ t_ct_h with T_ct_h = (T_w_t T_i_ct)⁻¹ T_w_h T_i_c0,
//           ∂r/∂δ_h = ∂r/∂T_ct_h · ∂T_ct_h/∂δ_h, ∂r/∂δ_t likewise (the relative-pose Jacobians
//           D_rel_h, D_rel_t of core/geometry/se3.h), ∂r/∂ℓ from transformLandmark; an
//           observation in the host frame itself has no pose Jacobian (T_ct_h is constant);
//   world   p_w (strategies dense / nfr): p_i = R_w_iᵀ(p_w − t_w_i) (the pose–landmark map of
//           core/sparsify/nfr.h, with its Jacobians), q = T_c_i p_i, ∂q/∂· = R_c_i ∂p_i/∂·.
//
// First-estimate Jacobians: the Jacobians are evaluated at the first estimates of the variables
// that are in the marginalization prior (q_jac), the residual at the current state (q); both must
// project (z ≥ min_depth) for the row to count.
//
// LandmarkJacobians stacks all rows of one landmark over the pose blocks it touches (in id order):
// [J_p | J_l | r], the input of the landmark elimination (core/linalg/landmark_block.h).

#include <cmath>
#include <cstdint>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/geometry/camera.h"
#include "core/geometry/se3.h"
#include "core/geometry/stereographic.h"
#include "core/sparsify/nfr.h"

namespace marglab {

// Huber cost of a reprojection error e (pixels), divided by σ²: ½e² inside, k·e − ½k² outside.
template <typename Scalar>
inline Scalar huberCost(Scalar e, Scalar k, Scalar sigma) {
  const Scalar c = e <= k ? Scalar(0.5) * e * e : k * e - Scalar(0.5) * k * k;
  return c / (sigma * sigma);
}

// The residual noise model: Huber threshold k and standard deviation σ, in pixels.
template <typename Scalar>
struct ReprojectionNoise {
  Scalar huber_px = 1;
  Scalar sigma_px = 1;
};

// One observation in one camera: two whitened rows with the Jacobians w.r.t. the host pose
// (hosted landmarks only), the target pose and the landmark.
template <typename Scalar>
struct ReprojectionRows {
  int64_t target = -1;  // −1: no pose Jacobian (observation in the host frame)
  int cam = 0;
  Mat<Scalar, 2, 6> J_h, J_t;
  Mat<Scalar, 2, 3> J_l;
  Vec<Scalar, 2> r;
  Scalar scale = 0;  // √w/σ: also ∂r_u/∂c_x, the Jacobian of the u row w.r.t. the camera's cx
};

// The point in the target camera and its Jacobians, at the first estimates (jac) and the current
// state. D_q_T is w.r.t. T_ct_h (hosted) or the target pose increment (world).
template <typename Scalar>
struct TargetPoint {
  Vec3<Scalar> q_jac, q;
  Mat<Scalar, 3, 3> D_q_l;
  Mat<Scalar, 3, 6> D_q_T;
};

// A hosted landmark ℓ seen through T_ct_h (current) and T_ct_h_jac (first estimates).

// The body-frame point of a world landmark at the first estimates, with its Jacobians (p_i_jac,
// D_p_T, D_p_l), and at the current state (p_i); then seen from camera T_c_i.
template <typename Scalar>
struct BodyPoint {
  Vec3<Scalar> p_i_jac = Vec3<Scalar>::Zero(), p_i = Vec3<Scalar>::Zero();
  Mat<Scalar, 3, 6> D_p_T = Mat<Scalar, 3, 6>::Zero();
  Mat3<Scalar> D_p_l = Mat3<Scalar>::Zero();
};

// Projects the target point and fills the whitened residual, J_l and the pose Jacobian w.r.t.
// the target point's D_q_T (into rows->J_t); adds the Huber cost to *cost. False when either point
// does not project.

// The Huber cost of one observation at the current state (0 when q does not project).

template <typename Scalar>
inline TargetPoint<Scalar> hostedTargetPoint(const SE3<Scalar>& T_ct_h_jac,
                                             const SE3<Scalar>& T_ct_h,
                                             const Vec3<Scalar>& landmark) {
  TargetPoint<Scalar> point;
  point.q_jac = transformLandmark<Scalar>(T_ct_h_jac, landmark, &point.D_q_l, &point.D_q_T);
  point.q = transformLandmark<Scalar>(T_ct_h, landmark);
  return point;
}

template <typename Scalar>
inline BodyPoint<Scalar> worldBodyPoint(const SE3<Scalar>& T_w_i_jac, const SE3<Scalar>& T_w_i,
                                        const Vec3<Scalar>& p_w_jac, const Vec3<Scalar>& p_w) {
  BodyPoint<Scalar> body;
  body.p_i_jac = poseLandmarkResidual<Scalar>(T_w_i_jac, p_w_jac, Vec3<Scalar>::Zero(), &body.D_p_T,
                                              &body.D_p_l);
  body.p_i = T_w_i.inverse() * p_w;
  return body;
}

template <typename Scalar>
inline TargetPoint<Scalar> worldTargetPoint(const SE3<Scalar>& T_c_i,
                                            const BodyPoint<Scalar>& body) {
  TargetPoint<Scalar> point;
  const Mat3<Scalar> R_c_i = T_c_i.rotationMatrix();
  point.q_jac = T_c_i * body.p_i_jac;
  point.D_q_T = R_c_i * body.D_p_T;
  point.D_q_l = R_c_i * body.D_p_l;
  point.q = T_c_i * body.p_i;
  return point;
}

template <typename Scalar>
inline bool linearizeReprojection(const PinholeCamera<Scalar>& camera,
                                  const TargetPoint<Scalar>& point, const Vec<Scalar, 2>& z,
                                  const ReprojectionNoise<Scalar>& noise,
                                  ReprojectionRows<Scalar>* rows, Scalar* cost) {
  Vec<Scalar, 2> uv_jac, uv;
  Mat<Scalar, 2, 3> D_uv_q;
  if (!camera.project(point.q_jac, &uv_jac, &D_uv_q)) return false;
  if (!camera.project(point.q, &uv)) return false;
  const Scalar k = noise.huber_px;
  const Scalar sigma = noise.sigma_px;
  rows->r = uv - z;
  const Scalar e = rows->r.norm();
  *cost += huberCost<Scalar>(e, k, sigma);
  // IRLS weight of the Huber norm, applied as √w/σ to both rows.
  const Scalar scale = std::sqrt(e <= k ? Scalar(1) : k / e) / sigma;
  rows->r *= scale;
  rows->scale = scale;
  rows->J_l = scale * D_uv_q * point.D_q_l;
  rows->J_t = scale * D_uv_q * point.D_q_T;
  return true;
}

template <typename Scalar>
inline Scalar reprojectionCost(const PinholeCamera<Scalar>& camera, const Vec3<Scalar>& q,
                               const Vec<Scalar, 2>& z, const ReprojectionNoise<Scalar>& noise) {
  Vec<Scalar, 2> uv;
  if (!camera.project(q, &uv)) return Scalar(0);
  return huberCost<Scalar>((uv - z).norm(), noise.huber_px, noise.sigma_px);
}

// One landmark linearized over the pose blocks of a system.
template <typename Scalar>
struct LandmarkJacobians {
  int64_t track_id = -1;
  std::vector<int64_t> frames;  // local pose blocks, in id order
  // J_p's last column is the right camera's cx offset (after the pose blocks; window.h).
  bool stereo_offset = false;
  MatX<Scalar> J_p;
  Mat<Scalar, Eigen::Dynamic, 3> J_l;
  VecX<Scalar> r;
  Scalar cost = 0;
};

// Extra rows of a landmark over [one pose | the landmark] (a recovered pose–landmark factor).
template <typename Scalar>
struct PoseLandmarkRows {
  int64_t frame = -1;
  MatX<Scalar> J;  // rows × (6 + 3)
  VecX<Scalar> r;
};

// Stacks the observation rows (then the extra rows) of landmark track_id into out: frames are the
// host (hosted landmarks with a pose row) and every target with a pose Jacobian, in id order.
// With stereo_offset and a right-camera row, J_p gets a last column: ∂r/∂c, c the offset added to
// cx of the right camera, √w/σ on its rows' u rows (every row, the host frame's included).
template <typename Scalar>
void stackLandmarkRows(int64_t track_id, int64_t host,
                       const std::vector<ReprojectionRows<Scalar>>& rows,
                       const std::vector<PoseLandmarkRows<Scalar>>& extra,
                       LandmarkJacobians<Scalar>* out, bool stereo_offset = false);

}  // namespace marglab
