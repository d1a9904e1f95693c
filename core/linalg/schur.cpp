#include "core/linalg/schur.h"

#include <fmt/core.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace marglab {

template <typename Scalar>
PseudoInverse<Scalar> pseudoInverseSelfAdjoint(const MatX<Scalar>& H,
                                               const PinvOptions<Scalar>& options) {
  PseudoInverse<Scalar> result;
  const Eigen::Index n = H.rows();
  if (n == 0) return result;
  Eigen::SelfAdjointEigenSolver<MatX<Scalar>> eig(H);
  const VecX<Scalar>& lambda = eig.eigenvalues();
  const Scalar lambda_abs_max = lambda.cwiseAbs().maxCoeff();
  if (options.mode == RankThresholdMode::kRelative) {
    const Scalar t = options.threshold >= 0
                         ? options.threshold
                         : NumericTraits<Scalar>::pinvRelativeTolerance(static_cast<int>(n));
    result.threshold_used = t * lambda_abs_max;
  } else {
    result.threshold_used = options.threshold >= 0 ? options.threshold : Scalar(0);
  }
  VecX<Scalar> lambda_pinv = VecX<Scalar>::Zero(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (std::abs(lambda[i]) > result.threshold_used) {
      lambda_pinv[i] = Scalar(1) / lambda[i];
      ++result.rank;
    }
  }
  result.H_pinv = eig.eigenvectors() * lambda_pinv.asDiagonal() * eig.eigenvectors().transpose();
  return result;
}

template <typename Scalar>
SchurMarginalization<Scalar> schurMarginalize(const MatX<Scalar>& H, const VecX<Scalar>& b,
                                              int n_marg, const PinvOptions<Scalar>& options) {
  SchurMarginalization<Scalar> result;
  const int n = static_cast<int>(H.rows());
  const int n_keep = n - n_marg;
  if (H.cols() != n || b.size() != n || n_marg < 0 || n_keep < 0) {
    result.status = Status::Error(
        Status::Code::kInvalidArgument,
        fmt::format("Schur complement: H is {}x{}, b has {} entries, {} to marginalize", H.rows(),
                    H.cols(), b.size(), n_marg));
    return result;
  }
  if (!H.allFinite() || !b.allFinite()) {
    result.status =
        Status::Error(Status::Code::kNotFinite, "Schur complement: H or b has a non-finite entry");
    return result;
  }
  const MatX<Scalar> H_mm =
      H.topLeftCorner(n_marg, n_marg).template selfadjointView<Eigen::Lower>();
  const PseudoInverse<Scalar> pinv = pseudoInverseSelfAdjoint<Scalar>(H_mm, options);
  result.marg_rank = pinv.rank;
  result.threshold_used = pinv.threshold_used;
  const auto H_km = H.bottomLeftCorner(n_keep, n_marg);
  const MatX<Scalar> H_km_H_mm_pinv = H_km * pinv.H_pinv;
  result.prior.H = H.bottomRightCorner(n_keep, n_keep) - H_km_H_mm_pinv * H_km.transpose();
  // Symmetrize: the product above is symmetric only up to rounding.
  result.prior.H = (Scalar(0.5) * (result.prior.H + result.prior.H.transpose())).eval();
  result.prior.b = b.tail(n_keep) - H_km_H_mm_pinv * b.head(n_marg);
  result.prior.c = Scalar(-0.5) * b.head(n_marg).dot(pinv.H_pinv * b.head(n_marg));
  if (!result.prior.H.allFinite() || !result.prior.b.allFinite()) {
    result.status = Status::Error(Status::Code::kNotFinite,
                                  "Schur complement: the marginalization prior is not finite");
  }
  return result;
}

template <typename Scalar>
LdltSqrt<Scalar> hessianToSqrtLdlt(const MatX<Scalar>& H, const VecX<Scalar>& b,
                                   Scalar relative_floor) {
  LdltSqrt<Scalar> result;
  const Eigen::Index n = H.rows();
  if (!H.allFinite() || !b.allFinite()) {
    result.status =
        Status::Error(Status::Code::kNotFinite, "LDLT square root: H or b has a non-finite entry");
    return result;
  }
  Eigen::LDLT<MatX<Scalar>> ldlt(H);
  // Eigen: H = Pᵀ L D Lᵀ P with P a product of transpositions.
  VecX<Scalar> D = ldlt.vectorD();
  // Without a floor the cut is exactly 0 (no product with max D that could be 0 · inf).
  const Scalar cut =
      relative_floor > Scalar(0) && n > 0 ? relative_floor * D.maxCoeff() : Scalar(0);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (D[i] < cut) {
      D[i] = Scalar(0);
      ++result.n_clamped;
    } else if (D[i] > Scalar(0)) {
      ++result.rank;
    }
  }
  const VecX<Scalar> sqrt_D = D.cwiseSqrt();
  const Eigen::PermutationMatrix<Eigen::Dynamic> P(ldlt.transpositionsP());
  const MatX<Scalar> Lt = ldlt.matrixU();
  result.prior.J = sqrt_D.asDiagonal() * (Lt * P);
  const VecX<Scalar> Pb = P * b;
  const VecX<Scalar> y = ldlt.matrixL().solve(Pb);  // L⁻¹ P b
  result.prior.r = VecX<Scalar>::Zero(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (sqrt_D[i] > Scalar(0)) result.prior.r[i] = y[i] / sqrt_D[i];
  }
  if (!result.prior.J.allFinite() || !result.prior.r.allFinite()) {
    result.status =
        Status::Error(Status::Code::kNotFinite, "LDLT square root: the factor is not finite");
  }
  return result;
}

#define MARGLAB_INST(S)                                                                         \
  template PseudoInverse<S> pseudoInverseSelfAdjoint<S>(const MatX<S>&, const PinvOptions<S>&); \
  template SchurMarginalization<S> schurMarginalize<S>(const MatX<S>&, const VecX<S>&, int,     \
                                                       const PinvOptions<S>&);                  \
  template LdltSqrt<S> hessianToSqrtLdlt<S>(const MatX<S>&, const VecX<S>&, S);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
