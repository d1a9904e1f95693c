#include "core/linalg/flat_qr.h"

#include <fmt/core.h>
#include <Eigen/Householder>

namespace marglab {

template <typename Scalar>
FlatQrInfo flatQrInPlace(Eigen::Ref<MatX<Scalar>> A, int n_cols, int n_prefix,
                         const FlatQrOptions<Scalar>& options) {
  const Eigen::Index N = A.rows();
  const Eigen::Index n_total = A.cols();
  FlatQrInfo info;
  info.pivot_row.assign(n_cols, -1);

  VecX<Scalar> column_threshold = VecX<Scalar>::Constant(n_cols, options.threshold);
  if (options.mode == RankThresholdMode::kRelative) {
    column_threshold = options.threshold * A.leftCols(n_cols).colwise().norm().transpose();
  }

  VecX<Scalar> essential_buffer(N);
  VecX<Scalar> workspace(n_total);
  Eigen::Index i = 0;
  for (int k = 0; k < n_cols; ++k) {
    if (k == n_prefix) info.rank_prefix = static_cast<int>(i);
    if (i >= N) continue;  // no rows left: every further column is dependent
    auto tail = A.col(k).segment(i, N - i);
    const Scalar beta_norm = tail.norm();
    if (!(beta_norm > column_threshold[k])) {
      tail.setZero();
      continue;
    }
    auto essential = essential_buffer.head(N - i - 1);
    Scalar tau;
    Scalar beta;
    tail.makeHouseholder(essential, tau, beta);
    A.block(i, k + 1, N - i, n_total - k - 1)
        .applyHouseholderOnTheLeft(essential, tau, workspace.data());
    A(i, k) = beta;
    A.col(k).segment(i + 1, N - i - 1).setZero();
    info.pivot_row[k] = static_cast<int>(i);
    ++i;
  }
  if (n_prefix >= n_cols) info.rank_prefix = static_cast<int>(i);
  info.rank = static_cast<int>(i);
  return info;
}

template <typename Scalar>
FlatQrMarginalization<Scalar> flatQrMarginalize(MatX<Scalar> A, int n_marg,
                                                const FlatQrOptions<Scalar>& options) {
  FlatQrMarginalization<Scalar> result;
  result.mode = options.mode;
  result.threshold = options.threshold;
  const int n_cols = static_cast<int>(A.cols()) - 1;
  const int n_keep = n_cols - n_marg;
  if (n_marg < 0 || n_keep < 0) {
    result.status = Status::Error(
        Status::Code::kInvalidArgument,
        fmt::format("flat QR: {} marginalized columns of {} in total", n_marg, n_cols));
    return result;
  }
  if (!A.allFinite()) {
    result.status = Status::Error(Status::Code::kNotFinite,
                                  "flat QR: the stacked system [J | r] has a non-finite entry");
    return result;
  }
  const FlatQrInfo info = flatQrInPlace<Scalar>(A, n_cols, n_marg, options);
  result.marg_rank = info.rank_prefix;
  result.total_rank = info.rank;
  const int prior_rows = std::max(1, info.rank - info.rank_prefix);
  result.prior.J = MatX<Scalar>::Zero(prior_rows, n_keep);
  result.prior.r = VecX<Scalar>::Zero(prior_rows);
  const int kept_rows = info.rank - info.rank_prefix;
  if (kept_rows > 0) {
    result.prior.J.topRows(kept_rows) = A.block(info.rank_prefix, n_marg, kept_rows, n_keep);
    result.prior.r.head(kept_rows) = A.col(n_cols).segment(info.rank_prefix, kept_rows);
  }
  return result;
}

#define MARGLAB_INST(S)                                                                         \
  template FlatQrInfo flatQrInPlace<S>(Eigen::Ref<MatX<S>>, int, int, const FlatQrOptions<S>&); \
  template FlatQrMarginalization<S> flatQrMarginalize<S>(MatX<S>, int, const FlatQrOptions<S>&);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
