#include "core/ceres_marg/sparse_cholesky.h"

#include <cholmod.h>
#include <fmt/core.h>

namespace marglab::ceres_marg {
namespace {

// A non-owning CHOLMOD view of the compressed-column matrix Aᵀ (the CRS arrays of A).
cholmod_sparse transposeView(const SparseRowMatrix& A) {
  cholmod_sparse view{};
  view.nrow = static_cast<std::size_t>(A.cols());
  view.ncol = static_cast<std::size_t>(A.rows());
  view.nzmax = static_cast<std::size_t>(A.nonZeros());
  view.p = const_cast<int*>(A.outerIndexPtr());
  view.i = const_cast<int*>(A.innerIndexPtr());
  view.x = const_cast<double*>(A.valuePtr());
  view.stype = 0;  // unsymmetric: CHOLMOD factorizes view · viewᵀ = AᵀA
  view.itype = CHOLMOD_INT;
  view.xtype = CHOLMOD_REAL;
  view.dtype = CHOLMOD_DOUBLE;
  view.sorted = 1;
  view.packed = 1;
  return view;
}

}  // namespace

SparseNormalCholesky::SparseNormalCholesky() : common_(new cholmod_common) {
  cholmod_start(common_);
  common_->print = 0;
  common_->final_ll = 1;  // LLᵀ also when CHOLMOD picks a simplicial LDLᵀ (solveForward)
}

SparseNormalCholesky::~SparseNormalCholesky() {
  if (factor_ != nullptr) cholmod_free_factor(&factor_, common_);
  cholmod_finish(common_);
  delete common_;
}

Status SparseNormalCholesky::factorize(const SparseRowMatrix& A) {
  if (factor_ != nullptr) cholmod_free_factor(&factor_, common_);
  if (!A.isCompressed()) {
    return Status::Error(Status::Code::kInvalidArgument, "sparse Cholesky: A is not compressed");
  }
  cholmod_sparse At = transposeView(A);
  factor_ = cholmod_analyze(&At, common_);
  if (factor_ == nullptr) {
    return Status::Error(Status::Code::kSolveFailed,
                         fmt::format("CHOLMOD analyze failed (status {})", common_->status));
  }
  cholmod_factorize(&At, factor_, common_);
  if (common_->status == CHOLMOD_NOT_POSDEF || factor_->minor < factor_->n) {
    return Status::Error(
        Status::Code::kRankDeficient,
        fmt::format("CHOLMOD: AᵀA ({0}x{0}) is not positive definite at column {1}", factor_->n,
                    factor_->minor));
  }
  if (common_->status < CHOLMOD_OK) {
    return Status::Error(Status::Code::kSolveFailed,
                         fmt::format("CHOLMOD factorize failed (status {})", common_->status));
  }
  return Status::Ok();
}

Status SparseNormalCholesky::solve(const MatXd& B, MatXd* X) const {
  return solveSystem(CHOLMOD_A, B, X);
}

Status SparseNormalCholesky::solveForward(const MatXd& B, MatXd* Y) const {
  MatXd PB;
  if (Status s = solveSystem(CHOLMOD_P, B, &PB); !s.ok()) return s;
  return solveSystem(CHOLMOD_L, PB, Y);
}

Status SparseNormalCholesky::solveSystem(int sys, const MatXd& B, MatXd* X) const {
  if (factor_ == nullptr || B.rows() != static_cast<Eigen::Index>(factor_->n)) {
    return Status::Error(Status::Code::kInvalidArgument,
                         "sparse Cholesky: no factorization or right-hand side of the wrong size");
  }
  cholmod_dense rhs{};
  rhs.nrow = static_cast<std::size_t>(B.rows());
  rhs.ncol = static_cast<std::size_t>(B.cols());
  rhs.nzmax = rhs.nrow * rhs.ncol;
  rhs.d = rhs.nrow;
  rhs.x = const_cast<double*>(B.data());
  rhs.xtype = CHOLMOD_REAL;
  rhs.dtype = CHOLMOD_DOUBLE;
  cholmod_dense* solution = cholmod_solve(sys, factor_, &rhs, common_);
  if (solution == nullptr) {
    return Status::Error(Status::Code::kSolveFailed,
                         fmt::format("CHOLMOD solve failed (status {})", common_->status));
  }
  *X = Eigen::Map<const MatXd>(static_cast<const double*>(solution->x), B.rows(), B.cols());
  cholmod_free_dense(&solution, common_);
  return X->allFinite()
             ? Status::Ok()
             : Status::Error(Status::Code::kNotFinite, "CHOLMOD solve: non-finite result");
}

}  // namespace marglab::ceres_marg
