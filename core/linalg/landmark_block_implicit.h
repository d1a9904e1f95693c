#pragma once
// Nullspace projection of one landmark with the projection kept implicit: for landmarks whose
// residual rows come in pairs that each touch one pose block (a bundle-adjustment observation:
// one camera), the reduced rows Q2ᵀJ_p are never formed.
//
// Same elimination as LandmarkBlockNs (landmark_block.h), another storage. With J_l = Q1 R1 (thin
// Householder QR; landmark damping diag(d) as three rows [0 | diag(√d)] below, folded by a QR of
// the 6 × 3 stack [R1; diag(√d)]), the damped thin factor Q1ᵈ ∈ ℝ^{(m+3)×3} is orthonormal and
// Q2ᵈQ2ᵈᵀ = I − Q1ᵈQ1ᵈᵀ. J_p's and r's three damping rows are zero, so with U = the top m rows
// of Q1ᵈ (its bottom 3 rows never meet a non-zero):
//     S_l x   = (Q2ᵀJ_p)ᵀ(Q2ᵀJ_p) x = J_pᵀ (t − U Uᵀt),   t = J_p x,
//     g_l     = (Q2ᵀJ_p)ᵀ Q2ᵀr     = J_pᵀ (r − U Uᵀr),
//     S_l,jj  = J_jᵀJ_j − A_jᵀA_j,  A_j = U_jᵀJ_j   (U_j: U's rows of observation j),
//     S_l,jk  = −A_jᵀA_k (j ≠ k),
//     δl      = −R1ᵈ⁻¹ Uᵀ(r + J_p δp).
// A product costs O(m) (t, Uᵀt, U(Uᵀt), J_pᵀ·: about 8·P + 24 flops per observation) where the
// explicit reduced rows cost O(m²) (an (m−3+3) × P·m/2 dense block, rootba's in-place storage):
// the landmark's observations are not coupled through a dense block.
//
// Rounding: the product's error is about ε‖J_p‖‖x‖ in both storages (the explicit rows are formed
// with that error); the camera blocks S_l,jj are a difference here (error ε‖J_j‖², which the
// Jacobian scaling bounds by ε), a Gram matrix in the explicit storage.
//
// The interface is the landmark-block interface of landmark_block.h, with the products of the
// matrix-free reduced camera system (reducedProduct, reducedGradient, reducedCameraBlock) in place
// of the explicit rows.

#include <vector>

#include "core/common/eigen_types.h"
#include "core/common/status.h"
#include "core/linalg/landmark_block.h"

namespace marglab {

template <typename S, int PoseDim>
class LandmarkBlockNsImplicit {
 public:
  using Scalar = S;
  static constexpr int kPoseDim = PoseDim;
  // Rows 2j, 2j+1 of J_obs (m × PoseDim) are observation j's Jacobian on pose block j of the map
  // (map.pose_dim == PoseDim); J_l: m × 3; r: m; m = 2 · blocks ≥ 4.
  Status setFromJacobians(const Eigen::Ref<const Mat<Scalar, Eigen::Dynamic, PoseDim>>& J_obs,
                          const Eigen::Ref<const Mat<Scalar, Eigen::Dynamic, 3>>& J_l,
                          const Eigen::Ref<const VecX<Scalar>>& r, const PoseBlockMap& map);
  const Vec3<Scalar>& landmarkHessianDiagonal() const { return H_ll_diagonal_; }
  void setLandmarkDamping(const Vec3<Scalar>& d);
  bool landmarkSolvable() const { return (R1_.diagonal().array() != Scalar(0)).all(); }

  // y = S_l x: x the reduced camera system's vector, y local (PoseDim per pose block, in map
  // order); t is scratch of at least m entries.
  void reducedProduct(const VecX<Scalar>& x, Scalar* t, Scalar* y) const;
  // y = g_l, local.
  void reducedGradient(Scalar* y) const;
  // S_l's diagonal block of local pose block j.
  Mat<Scalar, PoseDim, PoseDim> reducedCameraBlock(int j) const;
  // H += S_l, b += g_l on the reduced camera system (both triangles), in Scalar.
  Status addToReducedSystem(MatX<Scalar>& H, VecX<Scalar>& b) const;
  Status backSubstitute(const VecX<Scalar>& delta_rcs, Vec3<Scalar>* delta_l) const;
  // ½‖J_p δp + J_l δl + r‖² − ½‖r‖² = eᵀr + ½‖e‖² with e = J_p δp + J_l δl (undamped).
  Scalar linearizedCostChange(const VecX<Scalar>& delta_rcs, const Vec3<Scalar>& delta_l) const;
  const PoseBlockMap& map() const { return map_; }

 private:
  int blocks() const { return static_cast<int>(map_.rcs_offset.size()); }
  PoseBlockMap map_;
  Eigen::Matrix<Scalar, Eigen::Dynamic, PoseDim, Eigen::RowMajor> J_obs_;
  Mat<Scalar, Eigen::Dynamic, 3> J_l_;
  VecX<Scalar> r_;
  // The undamped factorization's reflectors: a member so that its storage is kept from one
  // linearization to the next (the landmark's rows do not change size).
  Mat<Scalar, Eigen::Dynamic, 3> reflectors_;
  Mat<Scalar, Eigen::Dynamic, 3> Q1_;  // thin Q of the undamped J_l
  Mat3<Scalar> R1_undamped_ = Mat3<Scalar>::Zero();
  // Top m rows of the damped thin Q, row-major (observation j's two rows contiguous), and R1ᵈ.
  Eigen::Matrix<Scalar, Eigen::Dynamic, 3, Eigen::RowMajor> U_;
  Mat3<Scalar> R1_ = Mat3<Scalar>::Zero();
  Vec3<Scalar> Ut_r_ = Vec3<Scalar>::Zero();  // Uᵀr
  Vec3<Scalar> H_ll_diagonal_ = Vec3<Scalar>::Zero();
};

}  // namespace marglab
