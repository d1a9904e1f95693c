#pragma once
// Symmetric block-diagonal preconditioning of a Hessian before a factorization
// (docs/preconditioned_storage.md; after Ke et al., "PC-SRIF", arXiv 2409.11372).
//
// A change of variables δ = P y with P block-diagonal turns the quadratic model
//     E(δ) = ½ δᵀ H δ + bᵀ δ     into     E = ½ yᵀ Ĥ y + b̂ᵀ y,    Ĥ = Pᵀ H P,  b̂ = Pᵀ b,
// the same function: a solve or a Schur complement of Ĥ is mapped back by δ = P y, and a stored
// Ĥ by H = Qᵀ Ĥ Q with Q = P⁻¹. P is built from the 3×3 diagonal blocks H_kk of H. Every state
// block of the window (pose [δt; δφ], speed-bias [δv; δb_g; δb_a], landmark point) is a multiple of
// three columns, so each 3×3 block is one physical quantity in one unit:
//   kJacobi       P_k = diag(s),  s_i = 2^−round(½ log2 H_ii)   (point Jacobi; powers of two, so the
//                 scaling itself is exact and Ĥ_ii ∈ [½, 2]);
//   kBlockJacobi  P_k = L_k⁻ᵀ with H_kk = L_k L_kᵀ (Cholesky of the block, computed in double),
//                 so Ĥ_kk = I: the units, scales and within-quantity correlations of each
//                 quantity are taken out. A block whose Cholesky fails (not positive definite in
//                 double) falls back to its Jacobi scales; a diagonal entry that is not positive
//                 and finite keeps the scale 1 (the factorization that follows reports it).
// Q_k is built beside P_k in double (L_kᵀ, or 1/s), so P and Q are inverse up to the rounding of
// one 3×3 block.

#include <vector>

#include "core/common/eigen_types.h"

namespace marglab {

enum class Preconditioning { kNone, kJacobi, kBlockJacobi };

template <typename Scalar>
class BlockScaling {
 public:
  static constexpr int kBlock = 3;

  // The identity on n columns (n a multiple of 3).
  static BlockScaling identity(int n);
  // P from the 3×3 diagonal blocks of the symmetric H (lower triangle read); kNone → identity.
  static BlockScaling fromHessian(const MatX<Scalar>& H, Preconditioning kind);

  int size() const { return kBlock * static_cast<int>(P_.size()); }
  bool empty() const { return P_.empty(); }

  MatX<Scalar> scaled(const MatX<Scalar>& H) const;              // Pᵀ H P (symmetric)
  VecX<Scalar> scaledGradient(const VecX<Scalar>& b) const;      // Pᵀ b
  VecX<Scalar> toDelta(const VecX<Scalar>& y) const;             // P y
  VecX<Scalar> toScaled(const VecX<Scalar>& delta) const;        // Q δ
  MatX<Scalar> unscaled(const MatX<Scalar>& H_s) const;          // Qᵀ Ĥ Q (symmetric)
  VecX<Scalar> unscaledGradient(const VecX<Scalar>& b_s) const;  // Qᵀ b̂
  MatX<Scalar> unscaledRows(const MatX<Scalar>& J_s) const;      // J_s Q: rows over y → over δ

  // The blocks from column `start` (a multiple of 3) on: the kept part after a marginalization.
  BlockScaling tail(int start) const;
  // The composition δ = P (P_inner z): blocks P_k P_inner,k and Q_inner,k Q_k.
  BlockScaling then(const BlockScaling& inner) const;

 private:
  std::vector<Mat3<Scalar>> P_, Q_;
};

}  // namespace marglab
