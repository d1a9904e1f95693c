#pragma once
// Elimination of one landmark from the linearized bundle-adjustment system, in two equivalent
// ways (Demmel et al., "Rootba: square root bundle adjustment", CVPR 2021; ICCV 2021 §4.1).
//
// A landmark l with m residual rows (m ≥ 3) contributes ½‖J_p δp + J_l δl + r‖² with J_p over the
// n_p pose columns it touches (blocks of pose_dim columns, mapped to the reduced camera system by
// the caller) and J_l ∈ ℝ^{m×3}.
//
// Nullspace projection (LandmarkBlockNs). Householder QR of J_l, applied in place to the dense
// block [J_p | J_l | r]:
//     Qᵀ[J_p | J_l | r] = ⎡Q1ᵀJ_p  R1  Q1ᵀr⎤  3 rows
//                         ⎣Q2ᵀJ_p   0  Q2ᵀr⎦  m − 3 rows
// For any δp the minimum over δl of the landmark's energy is ½‖Q2ᵀJ_p δp + Q2ᵀr‖² (Q2 spans the
// left nullspace of J_l), so the Q2ᵀ rows are the landmark's contribution to the reduced camera
// system, in square-root form; the Q1ᵀ rows give the back-substitution
//     δl = −R1⁻¹ (Q1ᵀr + Q1ᵀJ_p δp).
// Landmark damping diag(d) (LM) is three extra rows [0 | diag(√d) | 0] appended below; Givens
// rotations fold them into R1, which leaves three new rows with zeros under J_l that join the
// reduced system. The undamped factorization is kept, so the damping can be changed per LM trial.
//
// Schur complement (LandmarkBlockSc). With H_pp = J_pᵀJ_p, H_pl = J_pᵀJ_l, H_ll = J_lᵀJ_l +
// diag(d), b_p = J_pᵀr, b_l = J_lᵀr:
//     H_red = H_pp − H_pl H_ll⁻¹ H_lp,   b_red = b_p − H_pl H_ll⁻¹ b_l,
//     δl = −H_ll⁻¹ (b_l + H_lp δp).
// Both give the same reduced system in exact arithmetic: (Q2ᵀJ_p)ᵀ(Q2ᵀJ_p) = H_red since
// Q2Q2ᵀ = I − J_l(J_lᵀJ_l)⁻¹J_lᵀ; the square-root form avoids squaring the condition number.

#include <Eigen/Cholesky>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/common/status.h"

namespace marglab {

// Maps the landmark's local pose blocks to the reduced camera system: local block j (columns
// j·pose_dim .. (j+1)·pose_dim) goes to columns rcs_offset[j] .. rcs_offset[j] + pose_dim. A
// variable every landmark may share (a calibration, e.g. the stereo cx offset of
// core/estimator/window.h) is a trailing group of extra_cols local columns after the pose blocks,
// at columns extra_rcs_offset .. extra_rcs_offset + extra_cols of the reduced system; none by
// default.
struct PoseBlockMap {
  int pose_dim = 6;
  std::vector<int> rcs_offset;
  int extra_cols = 0;
  int extra_rcs_offset = 0;
  int poseCols() const { return pose_dim * static_cast<int>(rcs_offset.size()); }
  int localCols() const { return poseCols() + extra_cols; }
};

// The landmark-block interface both eliminations implement (core/estimator/linearization.h runs
// either through it):
//   Status setFromJacobians(J_p, J_l, r, map)      the landmark's rows over its pose blocks;
//   landmarkHessianDiagonal(), setLandmarkDamping(d) LM damping diag(d) of the landmark;
//   Status addToReducedSystem(H, b)                  its share of the reduced camera system (H of
//                                                    the block's precision or higher); fails, and
//                                                    adds nothing, when the landmark cannot be
//                                                    eliminated (singular R1 / H_ll + diag(d));
//   Status backSubstitute(δ_rcs, &δl), linearizedCostChange(δ_rcs, δl).
template <typename S>
class LandmarkBlockNs {
 public:
  using Scalar = S;
  // J_p: m × map.localCols(), J_l: m × 3, r: m, with m ≥ 3.
  Status setFromJacobians(const MatX<Scalar>& J_p, const Mat<Scalar, Eigen::Dynamic, 3>& J_l,
                          const VecX<Scalar>& r, PoseBlockMap map);
  // Diagonal of J_lᵀJ_l (available after setFromJacobians), for the LM damping rule.
  const Vec3<Scalar>& landmarkHessianDiagonal() const { return H_ll_diagonal_; }
  // Sets the landmark damping diag(d) (d = 0 removes it).
  void setLandmarkDamping(const Vec3<Scalar>& d);
  // False when R1 is singular: the landmark cannot be back-substituted.
  bool landmarkSolvable() const;

  int numReducedRows() const { return static_cast<int>(reduced_rows_); }
  // The reduced rows [Q2ᵀJ_p | Q2ᵀr] (plus the three damping rows when damped).
  auto reducedJp() const { return storage_.block(3, 0, reduced_rows_, n_p_); }
  auto reducedR() const { return storage_.col(n_p_ + 3).segment(3, reduced_rows_); }
  // H += (Q2ᵀJ_p)ᵀ(Q2ᵀJ_p), b += (Q2ᵀJ_p)ᵀQ2ᵀr on the reduced camera system (upper and lower),
  // formed in Scalar and accumulated in HScalar, only over the pose blocks the landmark touches,
  // one block row of its Gram matrix at a time (6-column pose blocks without extra columns; other
  // layouts: a rank update scattered by blocks). Fails (adds nothing) when R1 is singular.
  template <typename HScalar>
  Status addToReducedSystem(MatX<HScalar>& H, VecX<HScalar>& b) const;
  // Copies the reduced rows into rows [row, row + numReducedRows()) of a stacked square-root
  // system whose pose columns follow the map (other columns untouched) and whose last column is r.
  void copyReducedRows(Eigen::Ref<MatX<Scalar>> stacked, int row) const;
  // δl = −R1⁻¹(Q1ᵀr + Q1ᵀJ_p δp) with δp the full reduced-camera-system increment.
  Status backSubstitute(const VecX<Scalar>& delta_rcs, Vec3<Scalar>* delta_l) const;
  // Change of the undamped linearized cost ½‖J_p δp + J_l δl + r‖² − ½‖r‖², evaluated on the
  // rotated rows (Q is orthogonal), for the LM gain ratio.
  Scalar linearizedCostChange(const VecX<Scalar>& delta_rcs, const Vec3<Scalar>& delta_l) const;
  const PoseBlockMap& map() const { return map_; }

 private:
  PoseBlockMap map_;
  Eigen::Index m_ = 0;
  Eigen::Index n_p_ = 0;
  Eigen::Index reduced_rows_ = 0;
  // Rows: [3 Q1ᵀ rows | m − 3 Q2ᵀ rows | 3 damping rows]; columns [J_p | J_l | r]. Row-major:
  // the reflections and the pose-pair accumulation into the reduced system work on contiguous
  // rows (axpys that vectorize, no short reductions).
  Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> storage_;
  Mat<Scalar, 3, Eigen::Dynamic> undamped_top_;  // Q1ᵀ rows before damping
  Vec3<Scalar> H_ll_diagonal_ = Vec3<Scalar>::Zero();
};

template <typename S>
class LandmarkBlockSc {
 public:
  using Scalar = S;
  Status setFromJacobians(const MatX<Scalar>& J_p, const Mat<Scalar, Eigen::Dynamic, 3>& J_l,
                          const VecX<Scalar>& r, PoseBlockMap map);
  Vec3<Scalar> landmarkHessianDiagonal() const { return H_ll_.diagonal(); }
  void setLandmarkDamping(const Vec3<Scalar>& d) { damping_ = d; }
  // H += H_pp − H_pl H_ll⁻¹ H_lp, b += b_p − H_pl H_ll⁻¹ b_l. Fails if H_ll + diag(d) is singular.
  template <typename HScalar>
  Status addToReducedSystem(MatX<HScalar>& H, VecX<HScalar>& b) const;
  Status backSubstitute(const VecX<Scalar>& delta_rcs, Vec3<Scalar>* delta_l) const;
  // ½‖J δ + r‖² − ½‖r‖² = bᵀδ + ½ δᵀHδ with the undamped blocks, δ = (δp, δl).
  Scalar linearizedCostChange(const VecX<Scalar>& delta_rcs, const Vec3<Scalar>& delta_l) const;
  const PoseBlockMap& map() const { return map_; }

 private:
  Status dampedFactor(Eigen::LLT<Mat3<Scalar>>* llt) const;
  PoseBlockMap map_;
  MatX<Scalar> H_pp_;  // lower triangle
  Mat<Scalar, Eigen::Dynamic, 3> H_pl_;
  Mat3<Scalar> H_ll_ = Mat3<Scalar>::Zero();
  VecX<Scalar> b_p_;
  Vec3<Scalar> b_l_ = Vec3<Scalar>::Zero();
  Vec3<Scalar> damping_ = Vec3<Scalar>::Zero();
};

// The in-place Householder QR of the three landmark columns n_p .. n_p + 2 of the row-major
// m-row block A (row stride ld ≥ n_p + 4, columns [J_p | J_l | r]): each reflection acts on every
// other column; below the diagonal of the landmark columns it leaves zeros. Eigen's
// makeHouseholder convention (β = −sign(x₀)‖x‖).
template <typename Scalar>
void householderLandmarkColumns(Scalar* A, Eigen::Index ld, Eigen::Index m, Eigen::Index n_p);

// Gathers a landmark's local pose increment from the reduced-camera-system increment.
template <typename Scalar>
VecX<Scalar> gatherLocal(const PoseBlockMap& map, const VecX<Scalar>& delta_rcs);

}  // namespace marglab
