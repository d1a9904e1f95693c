#pragma once
// Sparse Cholesky of a normal matrix AᵀA by CHOLMOD (SuiteSparse), for the sparse Schur route of
// the marginalization and the linear recovery stage of the mass-spring experiment.
//
// A (N × n) is given in compressed-row form, which is the compressed-column form of Aᵀ (n × N).
// CHOLMOD factorizes P (Aᵀ)(Aᵀ)ᵀ Pᵀ = L Lᵀ when handed the unsymmetric Aᵀ, so AᵀA is never
// formed by the caller (CHOLMOD forms it internally, sparse). Fill-reducing ordering P is
// CHOLMOD's default (AMD, or the best of its tried methods). AᵀA must be positive definite; a
// semi-definite one fails with kRankDeficient and the index of the first non-positive pivot. The
// factor is always LLᵀ (final_ll), so that AᵀA = Pᵀ L Lᵀ P and Bᵀ(AᵀA)⁻¹B = YᵀY with
// Y = L⁻¹ P B: a Schur complement needs only the forward half of a solve (solveForward).

#include <Eigen/SparseCore>

#include "core/common/eigen_types.h"
#include "core/common/status.h"

struct cholmod_common_struct;
struct cholmod_factor_struct;

namespace marglab::ceres_marg {

using SparseRowMatrix = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;

class SparseNormalCholesky {
 public:
  SparseNormalCholesky();
  ~SparseNormalCholesky();
  SparseNormalCholesky(const SparseNormalCholesky&) = delete;
  SparseNormalCholesky& operator=(const SparseNormalCholesky&) = delete;

  // Symbolic analysis and numeric factorization of AᵀA (A compressed, row major).
  Status factorize(const SparseRowMatrix& A);
  // Solves (AᵀA) X = B for the last factorization; B is n × k.
  Status solve(const MatXd& B, MatXd* X) const;
  // Y = L⁻¹ P B (n × k), the forward half of solve(): Bᵀ(AᵀA)⁻¹C = (L⁻¹PB)ᵀ(L⁻¹PC).
  Status solveForward(const MatXd& B, MatXd* Y) const;

 private:
  cholmod_common_struct* common_;
  cholmod_factor_struct* factor_ = nullptr;
  // X = op(B) for one CHOLMOD system (CHOLMOD_A, _P, _L, ...).
  Status solveSystem(int sys, const MatXd& B, MatXd* X) const;
};

}  // namespace marglab::ceres_marg
