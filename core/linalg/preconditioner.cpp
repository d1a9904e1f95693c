#include "core/linalg/preconditioner.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <stdexcept>

#include "core/common/scalar.h"

namespace marglab {
namespace {

// The power of two nearest to 1/√h (1 when h is not a positive finite number).
double jacobiScale(double h) {
  if (!(h > 0) || !std::isfinite(h)) return 1.0;
  return std::ldexp(1.0, -static_cast<int>(std::lround(0.5 * std::log2(h))));
}

void checkColumns(int n) {
  if (n % 3 != 0) throw std::invalid_argument("BlockScaling: columns not a multiple of 3");
}

}  // namespace

template <typename Scalar>
BlockScaling<Scalar> BlockScaling<Scalar>::identity(int n) {
  checkColumns(n);
  BlockScaling s;
  s.P_.assign(static_cast<size_t>(n / kBlock), Mat3<Scalar>::Identity());
  s.Q_ = s.P_;
  return s;
}

template <typename Scalar>
BlockScaling<Scalar> BlockScaling<Scalar>::fromHessian(const MatX<Scalar>& H,
                                                       Preconditioning kind) {
  const int n = static_cast<int>(H.rows());
  BlockScaling s = identity(n);
  if (kind == Preconditioning::kNone) return s;
  for (int k = 0; k < n / kBlock; ++k) {
    const Mat3<double> H_kk = H.template block<3, 3>(kBlock * k, kBlock * k)
                                  .template selfadjointView<Eigen::Lower>()
                                  .toDenseMatrix()
                                  .template cast<double>();
    Mat3<double> P = Mat3<double>::Zero(), Q = Mat3<double>::Zero();
    const Eigen::LLT<Mat3<double>> llt(H_kk);
    if (kind == Preconditioning::kBlockJacobi && llt.info() == Eigen::Success &&
        llt.matrixLLT().allFinite()) {
      Q = llt.matrixU();
      P = llt.matrixU().solve(Mat3<double>::Identity());
    } else {
      for (int i = 0; i < kBlock; ++i) {
        P(i, i) = jacobiScale(H_kk(i, i));
        Q(i, i) = 1.0 / P(i, i);
      }
    }
    s.P_[static_cast<size_t>(k)] = P.cast<Scalar>();
    s.Q_[static_cast<size_t>(k)] = Q.cast<Scalar>();
  }
  return s;
}

namespace {

// Bᵀ H B for block-diagonal B (3×3 blocks), the upper triangle copied from the lower so that
// the result is exactly symmetric.
template <typename Scalar>
MatX<Scalar> congruence(const MatX<Scalar>& H, const std::vector<Mat3<Scalar>>& B) {
  if (static_cast<size_t>(H.rows()) != 3 * B.size() || H.rows() != H.cols()) {
    throw std::invalid_argument("BlockScaling: matrix size does not match the scaling");
  }
  MatX<Scalar> M = H;
  for (size_t k = 0; k < B.size(); ++k) {
    const Eigen::Index c = static_cast<Eigen::Index>(3 * k);
    M.middleCols(c, 3) = (M.middleCols(c, 3) * B[k]).eval();
  }
  for (size_t k = 0; k < B.size(); ++k) {
    const Eigen::Index r = static_cast<Eigen::Index>(3 * k);
    M.middleRows(r, 3) = (B[k].transpose() * M.middleRows(r, 3)).eval();
  }
  M.template triangularView<Eigen::StrictlyUpper>() = M.transpose();
  return M;
}

template <typename Scalar>
VecX<Scalar> blockApply(const VecX<Scalar>& v, const std::vector<Mat3<Scalar>>& B, bool transpose) {
  if (static_cast<size_t>(v.size()) != 3 * B.size()) {
    throw std::invalid_argument("BlockScaling: vector size does not match the scaling");
  }
  VecX<Scalar> out(v.size());
  for (size_t k = 0; k < B.size(); ++k) {
    const Eigen::Index r = static_cast<Eigen::Index>(3 * k);
    out.template segment<3>(r) = transpose ? (B[k].transpose() * v.template segment<3>(r)).eval()
                                           : (B[k] * v.template segment<3>(r)).eval();
  }
  return out;
}

}  // namespace

template <typename Scalar>
MatX<Scalar> BlockScaling<Scalar>::scaled(const MatX<Scalar>& H) const {
  return congruence(H, P_);
}

template <typename Scalar>
VecX<Scalar> BlockScaling<Scalar>::scaledGradient(const VecX<Scalar>& b) const {
  return blockApply(b, P_, true);
}

template <typename Scalar>
VecX<Scalar> BlockScaling<Scalar>::toDelta(const VecX<Scalar>& y) const {
  return blockApply(y, P_, false);
}

template <typename Scalar>
VecX<Scalar> BlockScaling<Scalar>::toScaled(const VecX<Scalar>& delta) const {
  return blockApply(delta, Q_, false);
}

template <typename Scalar>
MatX<Scalar> BlockScaling<Scalar>::unscaled(const MatX<Scalar>& H_s) const {
  return congruence(H_s, Q_);
}

template <typename Scalar>
VecX<Scalar> BlockScaling<Scalar>::unscaledGradient(const VecX<Scalar>& b_s) const {
  return blockApply(b_s, Q_, true);
}

template <typename Scalar>
MatX<Scalar> BlockScaling<Scalar>::unscaledRows(const MatX<Scalar>& J_s) const {
  if (static_cast<size_t>(J_s.cols()) != 3 * Q_.size()) {
    throw std::invalid_argument("BlockScaling: matrix size does not match the scaling");
  }
  MatX<Scalar> J = J_s;
  for (size_t k = 0; k < Q_.size(); ++k) {
    const Eigen::Index c = static_cast<Eigen::Index>(3 * k);
    J.middleCols(c, 3) = (J_s.middleCols(c, 3) * Q_[k]).eval();
  }
  return J;
}

template <typename Scalar>
BlockScaling<Scalar> BlockScaling<Scalar>::tail(int start) const {
  checkColumns(start);
  if (start > size()) throw std::invalid_argument("BlockScaling: tail beyond the end");
  BlockScaling s;
  s.P_.assign(P_.begin() + start / kBlock, P_.end());
  s.Q_.assign(Q_.begin() + start / kBlock, Q_.end());
  return s;
}

template <typename Scalar>
BlockScaling<Scalar> BlockScaling<Scalar>::then(const BlockScaling& inner) const {
  if (inner.P_.size() != P_.size()) {
    throw std::invalid_argument("BlockScaling: composition of different sizes");
  }
  BlockScaling s;
  for (size_t k = 0; k < P_.size(); ++k) {
    s.P_.push_back(P_[k] * inner.P_[k]);
    s.Q_.push_back(inner.Q_[k] * Q_[k]);
  }
  return s;
}

#define MARGLAB_INST(S) template class BlockScaling<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
