#include "core/linalg/landmark_block.h"

#include <fmt/core.h>
#include <Eigen/Cholesky>
#include <Eigen/Householder>
#include <Eigen/Jacobi>
#include <limits>
#include <type_traits>
#include <vector>

#include "core/common/scalar.h"
#include "core/linalg/landmark_block_common.h"

namespace marglab {
namespace {

using landmark_block_detail::checkInput;
using landmark_block_detail::gatherLocalScratch;
using landmark_block_detail::scatterReduced;

// The widest vector register of the ISA this copy is compiled for (core/isa_kernels.cmake).
#if defined(__AVX512F__)
constexpr int kVectorBytes = 64;
#elif defined(__AVX__)
constexpr int kVectorBytes = 32;
#else
constexpr int kVectorBytes = 16;
#endif

// Calls chunk(std::integral_constant<int, C'>{}, j') over the columns [j, n): chunks of C, then of
// C/2, C/4, ... down to one SSE register, and the last columns by one more SSE-register chunk that
// ends at n and overlaps columns already done (the chunk recomputes them identically), so
// n ≥ 16 bytes of Scalar. A chunk narrower than an SSE register, or a loop over the last columns,
// would be vectorized by GCC in half a register, where it does not fuse the multiply-add: another
// rounding than the fused code of the other columns.
template <int C, typename Scalar, typename Chunk>
void forColumnChunks(Eigen::Index j, Eigen::Index n, const Chunk& chunk) {
  for (; n - j >= C; j += C) chunk(std::integral_constant<int, C>{}, j);
  if (j == n) return;
  if constexpr (C * sizeof(Scalar) > 16) {
    forColumnChunks<C / 2, Scalar>(j, n, chunk);
  } else {
    chunk(std::integral_constant<int, C>{}, n - C);
  }
}

// G(0..6, j .. j + C) = Σ_k x_kᵀ row_k(j .. j + C) with x_k = row_k(xc .. xc + 6), over the first
// `rows` rows of the row-major A (row stride ld); G row-major with row stride ldg. The 6 × C sums
// stay in registers over the rows (six chains of C / lanes multiply-adds), summed in row order.
template <int C, typename Scalar>
void gramChunk(const Scalar* A, Eigen::Index ld, Eigen::Index rows, Eigen::Index xc, Eigen::Index j,
               Scalar* G, Eigen::Index ldg) {
  using RowC = Eigen::Matrix<Scalar, 1, C>;
  RowC g0 = RowC::Zero(), g1 = RowC::Zero(), g2 = RowC::Zero(), g3 = RowC::Zero(),
       g4 = RowC::Zero(), g5 = RowC::Zero();
  for (Eigen::Index k = 0; k < rows; ++k) {
    const Scalar* x = A + k * ld + xc;
    const Eigen::Map<const RowC> y(A + k * ld + j);
    g0 += x[0] * y;
    g1 += x[1] * y;
    g2 += x[2] * y;
    g3 += x[3] * y;
    g4 += x[4] * y;
    g5 += x[5] * y;
  }
  Eigen::Map<RowC>(G + j) = g0;
  Eigen::Map<RowC>(G + ldg + j) = g1;
  Eigen::Map<RowC>(G + 2 * ldg + j) = g2;
  Eigen::Map<RowC>(G + 3 * ldg + j) = g3;
  Eigen::Map<RowC>(G + 4 * ldg + j) = g4;
  Eigen::Map<RowC>(G + 5 * ldg + j) = g5;
}

// The reduced rows A (row-major, `rows` rows, row stride ld ≥ n_p + 4, pose blocks of 6 columns,
// r in column r_col) added straight into H and b, pose block by pose block: block row i of the
// local lower triangle, G_i = Σ_k a_kiᵀ [a_k0 … a_ki] (6 × 6(i + 1), two vector registers of
// columns at a time), goes to H(o_i, o_j) and its transpose to H(o_j, o_i); b(o_i) += Σ_k a_kiᵀ r_k
// (a 6 × 8 register block: 8 is a whole vector of every ISA; the two extra columns are the next
// block's or J_l's, discarded). Only the poses the landmark touches, no local system to zero and
// scatter; every sum in row order.
template <typename Scalar, typename HScalar>
void addPoseBlockPairs(const Scalar* A, Eigen::Index ld, Eigen::Index rows, Eigen::Index r_col,
                       const std::vector<int>& offsets, MatX<HScalar>& H, VecX<HScalar>& b) {
  using Row8 = Eigen::Map<const Eigen::Matrix<Scalar, 1, 8>>;
  using GramRow = Eigen::Map<const Eigen::Matrix<Scalar, 6, Eigen::Dynamic, Eigen::RowMajor>, 0,
                             Eigen::OuterStride<>>;
  constexpr int kChunk = 2 * kVectorBytes / static_cast<int>(sizeof(Scalar));
  const int n_blocks = static_cast<int>(offsets.size());
  thread_local std::vector<Scalar> G_buffer;
  const Eigen::Index ldg = 6 * n_blocks;
  G_buffer.resize(static_cast<size_t>(6 * ldg));
  for (int i = 0; i < n_blocks; ++i) {
    const int oi = offsets[static_cast<size_t>(i)];
    Eigen::Matrix<Scalar, 1, 8> b_i = Eigen::Matrix<Scalar, 1, 8>::Zero();
    for (Eigen::Index k = 0; k < rows; ++k) b_i += A[k * ld + r_col] * Row8(A + k * ld + 6 * i);
    b.template segment<6>(oi) += b_i.template head<6>().transpose().template cast<HScalar>();
    forColumnChunks<kChunk, Scalar>(0, 6 * (i + 1), [&](auto c, Eigen::Index j0) {
      gramChunk<decltype(c)::value>(A, ld, rows, 6 * i, j0, G_buffer.data(), ldg);
    });
    const GramRow G_i(G_buffer.data(), 6, 6 * (i + 1), Eigen::OuterStride<>(ldg));
    for (int j = 0; j <= i; ++j) {
      const int oj = offsets[static_cast<size_t>(j)];
      const Eigen::Matrix<HScalar, 6, 6> block =
          G_i.template block<6, 6>(0, 6 * j).template cast<HScalar>();
      H.template block<6, 6>(oi, oj) += block;
      if (j != i) H.template block<6, 6>(oj, oi) += block.transpose();
    }
  }
}

// w(j .. j + C) = row_k + Σ_{i = k+1}^{m−1} v_i row_i over C columns from j, summed in row order.
// The C sums stay in registers over the rows: a running sum kept in memory would chain every
// row's multiply-add through a store and a reload (store-forwarding latency), which was the
// kernel's bottleneck. Each column's sum is the same sequence of operations either way.
template <int C, typename Scalar>
void reflectorProductChunk(const Scalar* A, Eigen::Index ld, Eigen::Index k, Eigen::Index m,
                           const Scalar* v, Eigen::Index j, Scalar* w) {
  using Chunk = Eigen::Array<Scalar, C, 1>;
  Chunk acc = Eigen::Map<const Chunk>(A + k * ld + j);
  for (Eigen::Index i = k + 1; i < m; ++i) acc += v[i] * Eigen::Map<const Chunk>(A + i * ld + j);
  Eigen::Map<Chunk>(w + j) = acc;
}

}  // namespace

template <typename Scalar>
void householderLandmarkColumns(Scalar* A, Eigen::Index ld, Eigen::Index m, Eigen::Index n_p) {
  // Row-major: row i starts at A + i·ld. For x = A(k.., n_p + k) = [c0; tail]:
  // β = −sign(c0)·‖x‖, v = [1; tail/(c0 − β)], τ = (β − c0)/β, no reflection (τ = 0) when
  // ‖tail‖² ≤ the smallest normal number. Applied as w = τ(row_k + Σ_i v_i row_i),
  // row_i −= v_i w: axpys along the contiguous rows.
  const Eigen::Index n_total = n_p + 4;
  thread_local std::vector<Scalar> v_buf, w_buf;
  v_buf.resize(static_cast<size_t>(m));
  w_buf.resize(static_cast<size_t>(n_total));
  Scalar* v = v_buf.data();
  Scalar* w = w_buf.data();
  for (Eigen::Index k = 0; k < 3; ++k) {
    const Eigen::Index col = n_p + k;
    const Scalar c0 = A[k * ld + col];
    Scalar tail_sq = 0;
    for (Eigen::Index i = k + 1; i < m; ++i) tail_sq += A[i * ld + col] * A[i * ld + col];
    if (tail_sq > std::numeric_limits<Scalar>::min()) {
      Scalar beta = std::sqrt(c0 * c0 + tail_sq);
      if (c0 >= Scalar(0)) beta = -beta;
      const Scalar denom = c0 - beta;
      for (Eigen::Index i = k + 1; i < m; ++i) v[i] = A[i * ld + col] / denom;
      const Scalar tau = (beta - c0) / beta;
      // Four vector registers of sums at a time: independent multiply-add chains.
      constexpr int kChunk = 4 * kVectorBytes / static_cast<int>(sizeof(Scalar));
      forColumnChunks<kChunk, Scalar>(0, n_total, [&](auto c, Eigen::Index j0) {
        reflectorProductChunk<decltype(c)::value>(A, ld, k, m, v, j0, w);
      });
      for (Eigen::Index j = 0; j < n_total; ++j) w[j] *= tau;
      Scalar* row_k_mut = A + k * ld;
      for (Eigen::Index j = 0; j < n_total; ++j) row_k_mut[j] -= w[j];
      for (Eigen::Index i = k + 1; i < m; ++i) {
        const Scalar vi = v[i];
        Scalar* row = A + i * ld;
        for (Eigen::Index j = 0; j < n_total; ++j) row[j] -= vi * w[j];
      }
      A[k * ld + col] = beta;
    }
    for (Eigen::Index i = k + 1; i < m; ++i) A[i * ld + col] = Scalar(0);
  }
}

template <typename Scalar>
VecX<Scalar> gatherLocal(const PoseBlockMap& map, const VecX<Scalar>& delta_rcs) {
  VecX<Scalar> local(map.localCols());
  for (size_t j = 0; j < map.rcs_offset.size(); ++j) {
    local.segment(j * map.pose_dim, map.pose_dim) =
        delta_rcs.segment(map.rcs_offset[j], map.pose_dim);
  }
  local.tail(map.extra_cols) = delta_rcs.segment(map.extra_rcs_offset, map.extra_cols);
  return local;
}

template <typename Scalar>
Status LandmarkBlockNs<Scalar>::setFromJacobians(const MatX<Scalar>& J_p,
                                                 const Mat<Scalar, Eigen::Dynamic, 3>& J_l,
                                                 const VecX<Scalar>& r, PoseBlockMap map) {
  Status status = checkInput(J_p, J_l, r, map);
  if (!status.ok()) return status;
  map_ = std::move(map);
  m_ = J_l.rows();
  n_p_ = J_p.cols();
  const Eigen::Index n_total = n_p_ + 4;
  storage_.resize(m_ + 3, n_total);
  storage_.topLeftCorner(m_, n_p_) = J_p;
  storage_.block(0, n_p_, m_, 3) = J_l;
  storage_.col(n_p_ + 3).head(m_) = r;
  storage_.bottomRows(3).setZero();
  H_ll_diagonal_ = J_l.colwise().squaredNorm().transpose();
  householderLandmarkColumns(storage_.data(), storage_.cols(), m_, n_p_);
  undamped_top_ = storage_.topRows(3);
  reduced_rows_ = m_ - 3;
  return Status::Ok();
}

template <typename Scalar>
void LandmarkBlockNs<Scalar>::setLandmarkDamping(const Vec3<Scalar>& d) {
  storage_.topRows(3) = undamped_top_;
  storage_.bottomRows(3).setZero();
  if ((d.array() <= Scalar(0)).all()) {
    reduced_rows_ = m_ - 3;
    return;
  }
  for (int j = 0; j < 3; ++j) {
    const Eigen::Index damping_row = m_ + j;
    storage_(damping_row, n_p_ + j) = std::sqrt(std::max(d[j], Scalar(0)));
    for (int c = j; c < 3; ++c) {
      Eigen::JacobiRotation<Scalar> G;
      G.makeGivens(storage_(c, n_p_ + c), storage_(damping_row, n_p_ + c));
      storage_.applyOnTheLeft(c, damping_row, G.adjoint());
      storage_(damping_row, n_p_ + c) = Scalar(0);
    }
  }
  reduced_rows_ = m_;
}

template <typename Scalar>
bool LandmarkBlockNs<Scalar>::landmarkSolvable() const {
  return (storage_.block(0, n_p_, 3, 3).diagonal().array() != Scalar(0)).all();
}

template <typename Scalar>
template <typename HScalar>
Status LandmarkBlockNs<Scalar>::addToReducedSystem(MatX<HScalar>& H, VecX<HScalar>& b) const {
  if (!landmarkSolvable()) {
    return Status::Error(Status::Code::kRankDeficient,
                         "landmark elimination: R1 is singular (landmark not observable)");
  }
  if (map_.pose_dim == 6 && map_.extra_cols == 0) {
    addPoseBlockPairs(storage_.data() + 3 * storage_.cols(), storage_.cols(), reduced_rows_,
                      n_p_ + 3, map_.rcs_offset, H, b);
    return Status::Ok();
  }
  // Other layouts: Eigen's symmetric rank update (lower triangle) into a per-thread local
  // system that keeps its storage, scattered block by block.
  const auto Jr = reducedJp();
  thread_local MatX<Scalar> H_loc;
  thread_local VecX<Scalar> b_loc;
  if (H_loc.rows() != n_p_) H_loc.resize(n_p_, n_p_);
  H_loc.setZero();
  H_loc.template selfadjointView<Eigen::Lower>().rankUpdate(Jr.transpose());
  if (b_loc.size() != n_p_) b_loc.resize(n_p_);
  b_loc.noalias() = Jr.transpose() * reducedR();
  scatterReduced(map_, H_loc, b_loc, H, b);
  return Status::Ok();
}

template <typename Scalar>
void LandmarkBlockNs<Scalar>::copyReducedRows(Eigen::Ref<MatX<Scalar>> stacked, int row) const {
  const int pd = map_.pose_dim;
  for (size_t j = 0; j < map_.rcs_offset.size(); ++j) {
    stacked.block(row, map_.rcs_offset[j], reduced_rows_, pd) =
        storage_.block(3, j * pd, reduced_rows_, pd);
  }
  stacked.block(row, map_.extra_rcs_offset, reduced_rows_, map_.extra_cols) =
      storage_.block(3, map_.poseCols(), reduced_rows_, map_.extra_cols);
  stacked.col(stacked.cols() - 1).segment(row, reduced_rows_) = reducedR();
}

template <typename Scalar>
Status LandmarkBlockNs<Scalar>::backSubstitute(const VecX<Scalar>& delta_rcs,
                                               Vec3<Scalar>* delta_l) const {
  const auto delta_p = gatherLocalScratch(map_, delta_rcs);
  const Vec3<Scalar> rhs =
      storage_.topLeftCorner(3, n_p_) * delta_p + storage_.col(n_p_ + 3).head(3);
  // A fixed-size row-major copy: the same row-by-row substitution as on the dynamic block (sums
  // of at most two products, so the same rounding), without the dynamic kernel's vector paths.
  const Eigen::Matrix<Scalar, 3, 3, Eigen::RowMajor> R1 = storage_.template block<3, 3>(0, n_p_);
  if ((R1.diagonal().array() == Scalar(0)).any()) {
    return Status::Error(Status::Code::kRankDeficient,
                         "landmark back-substitution: R1 is singular (landmark not observable)");
  }
  *delta_l = -R1.template triangularView<Eigen::Upper>().solve(rhs);
  if (!delta_l->allFinite()) {
    return Status::Error(Status::Code::kNotFinite, "landmark back-substitution: non-finite step");
  }
  return Status::Ok();
}

template <typename Scalar>
Scalar LandmarkBlockNs<Scalar>::linearizedCostChange(const VecX<Scalar>& delta_rcs,
                                                     const Vec3<Scalar>& delta_l) const {
  const auto delta_p = gatherLocalScratch(map_, delta_rcs);
  const Vec3<Scalar> top_r = undamped_top_.col(n_p_ + 3);
  const Vec3<Scalar> top =
      undamped_top_.leftCols(n_p_) * delta_p + undamped_top_.block(0, n_p_, 3, 3) * delta_l + top_r;
  const auto Q2_Jp = storage_.block(3, 0, m_ - 3, n_p_);
  const auto Q2_r = storage_.col(n_p_ + 3).segment(3, m_ - 3);
  // ‖Q2ᵀJ_p δp + Q2ᵀr‖² − ‖Q2ᵀr‖² = ‖Q2ᵀJ_p δp‖² + 2 (Q2ᵀr)ᵀ Q2ᵀJ_p δp, column by column.
  thread_local std::vector<Scalar> buffer;
  buffer.resize(static_cast<size_t>(m_ - 3));
  Eigen::Map<VecX<Scalar>> J_step(buffer.data(), m_ - 3);
  J_step.noalias() = Q2_Jp * delta_p;
  return Scalar(0.5) * (top.squaredNorm() - top_r.squaredNorm() + J_step.squaredNorm() +
                        Scalar(2) * Q2_r.dot(J_step));
}

#define MARGLAB_INST(S)                                                                \
  template class LandmarkBlockNs<S>;                                                   \
  template Status LandmarkBlockNs<S>::addToReducedSystem<S>(MatX<S>&, VecX<S>&) const; \
  template VecX<S> gatherLocal<S>(const PoseBlockMap&, const VecX<S>&);                \
  template void householderLandmarkColumns<S>(S*, Eigen::Index, Eigen::Index, Eigen::Index);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST
#if defined(MARGLAB_WITH_FLOAT)
// Mixed precision: float landmark blocks in a double reduced system.
template Status LandmarkBlockNs<float>::addToReducedSystem<double>(MatX<double>&,
                                                                   VecX<double>&) const;
#endif

}  // namespace marglab
