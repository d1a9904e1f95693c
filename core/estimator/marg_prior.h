#pragma once
// The marginalization prior of the sliding window (paper §3.1.3), over a list of pose variables
// (6 dof each, increment δ = [δt; δφ] of core/geometry/se3.h), in one of two storages:
//   square root (eq. 4):  E_m(x) = ½ ‖r_m + J_m δ‖²,
//   Hessian     (eq. 3):  E_m(x) = ½ δᵀ H_m δ + b_mᵀ δ,          δ = x ⊟ x⁰,
// where x⁰ are the first-estimate linearization points of the prior's variables. The shift of
// the expansion point (eq. 6: r' = r_m + J_m δ, b' = b_m + H_m δ) is applied on the fly from the
// stored (r_m, b_m) and x⁰, so the stored prior never changes between marginalizations.

#include <cstdint>
#include <functional>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/estimator/variant.h"
#include "core/geometry/se3.h"
#include "core/linalg/schur.h"

namespace marglab {

template <typename Scalar>
struct MargPrior {
  static constexpr int kPoseDim = 6;
  PriorStorage storage = PriorStorage::kSqrt;
  std::vector<int64_t> frame_ids;  // variable layout: pose blocks in this order
  std::vector<SE3<Scalar>> x0;     // linearization points, one per frame id
  SqrtPrior<Scalar> sqrt;          // used when storage == kSqrt
  HessianPrior<Scalar> hessian;    // used when storage == kHessian

  bool empty() const { return frame_ids.empty(); }
  int cols() const { return kPoseDim * static_cast<int>(frame_ids.size()); }
  int rows() const;
  // Index of a frame in the layout, or −1.
  int indexOf(int64_t frame_id) const;

  // δ = x ⊟ x⁰ stacked over the layout, poses looked up by frame id.
  VecX<Scalar> delta(const std::function<SE3<Scalar>(int64_t)>& pose_of) const;
  // E_m at δ.
  Scalar cost(const VecX<Scalar>& delta) const;
  // Gradient and Hessian at δ: b = Jᵀ(r + Jδ), H = JᵀJ  |  b = b_m + H_m δ, H = H_m.
  void linearize(const VecX<Scalar>& delta, MatX<Scalar>* H, VecX<Scalar>* b) const;
  // Residual rows at δ (square-root storage only): [J_m | r_m + J_m δ].
  void sqrtRows(const VecX<Scalar>& delta, MatX<Scalar>* J, VecX<Scalar>* r) const;
  // Change of E_m along a step s from δ (exact: E_m is quadratic in δ).
  Scalar costChange(const VecX<Scalar>& delta, const VecX<Scalar>& step) const;
};

}  // namespace marglab
