#pragma once
// The marginalization prior of the sliding window (paper §3.1.3), over a list of state blocks —
// poses (6 dof, increment δ = [δt; δφ] of core/geometry/se3.h), for VIO speed-bias blocks
// (9 dof, δ = [δv; δb_g; δb_a] of core/imu/imu_state.h), and with the `dense` marginalization
// strategy landmarks as world points (3 dof, additive) — in one of two storages:
//   square root (eq. 4):  E_m(x) = ½ ‖r_m + J_m δ‖²,
//   Hessian     (eq. 3):  E_m(x) = ½ δᵀ H_m δ + b_mᵀ δ,          δ = x ⊟ x⁰,
// where x⁰ are the first-estimate linearization points of the prior's variables. The
// preconditioned Hessian storages (sqp, sqj; core/linalg/preconditioner.h) keep the same E_m in
// scaled coordinates y = Q δ:  E_m = ½ yᵀ Ĥ_m y + b̂_mᵀ y + c, i.e. H_m = Qᵀ Ĥ_m Q, b_m = Qᵀ b̂_m,
// with `hessian` holding (Ĥ_m, b̂_m, c) and `scaling` the P (and Q = P⁻¹) of the layout. The shift of
// the expansion point (eq. 6: r' = r_m + J_m δ, b' = b_m + H_m δ) is applied on the fly from the
// stored (r_m, b_m) and x⁰, so the stored prior never changes between marginalizations.

#include <cstdint>
#include <functional>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/diagnostics/gauge.h"
#include "core/estimator/variant.h"
#include "core/geometry/se3.h"
#include "core/linalg/preconditioner.h"
#include "core/linalg/schur.h"

namespace marglab {

// The two kinds of state block of a frame: its pose, and (VIO, latest states only) velocity and
// biases together; a landmark kept as a world point in a dense prior (its id is the track id);
// and the window's one calibration variable, the right camera's cx offset in pixels
// ([estimator] estimate_right_cx_offset, window.h; additive, key kStereoOffsetVar).
enum class StateBlock : int { kPose = 0, kSpeedBias = 1, kLandmark = 2, kStereoOffset = 3 };
constexpr int kPoseDim = 6;
constexpr int kSpeedBiasDim = 9;
constexpr int kPointDim = 3;
constexpr int kStereoOffsetDim = 1;
constexpr int stateBlockDim(StateBlock block) {
  switch (block) {
    case StateBlock::kPose:
      return kPoseDim;
    case StateBlock::kSpeedBias:
      return kSpeedBiasDim;
    case StateBlock::kLandmark:
      return kPointDim;
    case StateBlock::kStereoOffset:
      return kStereoOffsetDim;
  }
  return 0;
}

// One variable of the window: a block of one frame (frame_id), or a landmark (frame_id holds its
// track id). Ordered by id, pose before speed-bias before landmark.
struct VarKey {
  int64_t frame_id = 0;
  StateBlock block = StateBlock::kPose;
  bool operator<(const VarKey& o) const {
    return frame_id != o.frame_id ? frame_id < o.frame_id : block < o.block;
  }
  bool operator==(const VarKey& o) const { return frame_id == o.frame_id && block == o.block; }
};
// The stereo cx offset: one per window, no frame.
inline constexpr VarKey kStereoOffsetVar{-1, StateBlock::kStereoOffset};

// The preconditioning a storage applies before its factorizations.
constexpr Preconditioning preconditioningOf(const PriorStorage& storage) {
  return storage.preconditioning;
}

template <typename Scalar>
struct MargPrior {
  using Vec9S = Vec<Scalar, kSpeedBiasDim>;
  struct Block {
    VarKey var;
    int offset = 0;
    SE3<Scalar> T0;                          // linearization point of a pose block
    Vec9S sb0 = Vec9S::Zero();               // linearization point of a speed-bias block
    Vec3<Scalar> p0 = Vec3<Scalar>::Zero();  // linearization point p_w of a landmark block
    Scalar c0 = 0;                           // linearization point of the stereo offset
  };

  PriorStorage storage;
  std::vector<Block> blocks;     // variable layout, in column order
  SqrtPrior<Scalar> sqrt;        // used by every square-root storage (unscaled for sqrtp)
  HessianPrior<Scalar> hessian;  // used by every Hessian storage (scaled for sqp, sqj)
  BlockScaling<Scalar> scaling;  // sqp, sqj: y = Q δ of `hessian`; empty otherwise

  bool empty() const { return blocks.empty(); }
  int cols() const;
  int rows() const;
  // Appends a block at the end of the layout.
  void addBlock(const VarKey& var, const SE3<Scalar>& T0, const Vec9S& sb0,
                const Vec3<Scalar>& p0 = Vec3<Scalar>::Zero());
  bool hasLandmarks() const;
  // Index of a variable in the layout, or −1.
  int indexOf(const VarKey& var) const;

  // δ = x ⊟ x⁰ stacked over the layout, current values looked up by frame / track id (point_of
  // is needed only with landmark blocks, stereo_offset only with the stereo offset's block).
  VecX<Scalar> delta(const std::function<SE3<Scalar>(int64_t)>& pose_of,
                     const std::function<Vec9S(int64_t)>& speed_bias_of,
                     const std::function<Vec3<Scalar>(int64_t)>& point_of = {},
                     Scalar stereo_offset = 0) const;
  bool scaled() const { return !scaling.empty(); }
  // The stored expansion at δ = 0: Hessian JᵀJ | H_m and gradient Jᵀr | b_m (unscaled).
  MatX<Scalar> hessianAtAnchor() const;
  VecX<Scalar> gradientAtAnchor() const;
  // Replaces the stored expansion (the layout stays); setHessian clears the scaling, setScaledHessian
  // stores (Ĥ_m, b̂_m, c) with their scaling.
  void setSqrt(MatX<Scalar> J, VecX<Scalar> r);
  void setHessian(MatX<Scalar> H, VecX<Scalar> b, Scalar c);
  void setScaledHessian(MatX<Scalar> H_s, VecX<Scalar> b_s, Scalar c, BlockScaling<Scalar> P);
  // An unscaled Hessian prior moved to the scaled form of the storage's preconditioning (a window
  // restored from a snapshot, the initial gauge prior); nothing for the other storages (sqrtp's
  // preconditioning acts in its marginalization, its stored J is unscaled).
  void precondition();
  // E_m at δ.
  Scalar cost(const VecX<Scalar>& delta) const;
  // Gradient and Hessian at δ: b = Jᵀ(r + Jδ), H = JᵀJ  |  b = b_m + H_m δ, H = H_m.
  void linearize(const VecX<Scalar>& delta, MatX<Scalar>* H, VecX<Scalar>* b) const;
  // Residual rows at δ (square-root storage only): [J_m | r_m + J_m δ].
  void sqrtRows(const VecX<Scalar>& delta, MatX<Scalar>* J, VecX<Scalar>* r) const;
  // Change of E_m along a step s from δ (exact: E_m is quadratic in δ).
  Scalar costChange(const VecX<Scalar>& delta, const VecX<Scalar>& step) const;
  // The layout in the gauge diagnostics' terms (core/diagnostics/gauge.h), with the linearization
  // points x⁰ as their state: the gauge directions of this prior lie there (first estimates).
  void gaugeLayout(PriorLayout* layout, GaugeState* state) const;
};

}  // namespace marglab
