#pragma once
// Helpers shared by the two landmark eliminations (landmark_block.cpp: nullspace,
// landmark_block_sc.cpp: Schur complement). Internal to core/linalg. The eliminations live in
// separate translation units so that an optimization of one does not change the compiler's
// inlining (and, with FMA contraction, the rounding) of the other.

#include <fmt/core.h>

#include <type_traits>
#include <vector>

#include "core/linalg/landmark_block.h"

namespace marglab::landmark_block_detail {

template <typename Scalar>
Status checkInput(const MatX<Scalar>& J_p, const Mat<Scalar, Eigen::Dynamic, 3>& J_l,
                  const VecX<Scalar>& r, const PoseBlockMap& map) {
  const Eigen::Index m = J_l.rows();
  if (m < 3 || J_p.rows() != m || r.size() != m || J_p.cols() != map.localCols()) {
    return Status::Error(
        Status::Code::kInvalidArgument,
        fmt::format("landmark block: J_p {}x{}, J_l {}x3, r {} with {} pose "
                    "blocks of {} (needs ≥ 3 consistent rows)",
                    J_p.rows(), J_p.cols(), m, r.size(), map.rcs_offset.size(), map.pose_dim));
  }
  // J_p is not scanned: a non-finite entry reaches the reduced system, whose solve reports it.
  if (!J_l.allFinite() || !r.allFinite()) {
    return Status::Error(Status::Code::kNotFinite,
                         "landmark block: non-finite Jacobian or residual");
  }
  return Status::Ok();
}

// Adds a local system whose H_loc holds only its lower triangle (from a symmetric rank update,
// half the flops of a full product) to both triangles of the global H. PD is the pose block size
// when known at compile time (fixed-size block copies), Eigen::Dynamic otherwise.
template <int PD, typename Scalar, typename HScalar>
void scatterReducedBlocks(const PoseBlockMap& map, const MatX<Scalar>& H_loc_lower,
                          const VecX<Scalar>& b_loc, MatX<HScalar>& H, VecX<HScalar>& b) {
  const int pd = map.pose_dim;
  const int n_blocks = static_cast<int>(map.rcs_offset.size());
  for (int i = 0; i < n_blocks; ++i) {
    const int oi = map.rcs_offset[i];
    b.template segment<PD>(oi, pd) +=
        b_loc.template segment<PD>(i * pd, pd).template cast<HScalar>();
    if constexpr (std::is_same_v<Scalar, HScalar>) {
      H.template block<PD, PD>(oi, oi, pd, pd) +=
          H_loc_lower.template block<PD, PD>(i * pd, i * pd, pd, pd)
              .template selfadjointView<Eigen::Lower>();
    } else {
      const Eigen::Matrix<Scalar, PD, PD> diag =
          H_loc_lower.template block<PD, PD>(i * pd, i * pd, pd, pd)
              .template selfadjointView<Eigen::Lower>();
      H.template block<PD, PD>(oi, oi, pd, pd) += diag.template cast<HScalar>();
    }
    for (int j = 0; j < i; ++j) {
      const int oj = map.rcs_offset[j];
      const auto block =
          H_loc_lower.template block<PD, PD>(i * pd, j * pd, pd, pd).template cast<HScalar>();
      H.template block<PD, PD>(oi, oj, pd, pd) += block;
      H.template block<PD, PD>(oj, oi, pd, pd) += block.transpose();
    }
  }
}

// The trailing extra columns (PoseBlockMap): their rows of the local lower triangle against the
// pose blocks (both triangles of H) and against themselves.
template <typename Scalar, typename HScalar>
void scatterReducedExtra(const PoseBlockMap& map, const MatX<Scalar>& H_loc_lower,
                         const VecX<Scalar>& b_loc, MatX<HScalar>& H, VecX<HScalar>& b) {
  const int pd = map.pose_dim;
  const int e0 = map.poseCols();
  const int ne = map.extra_cols;
  const int oe = map.extra_rcs_offset;
  b.segment(oe, ne) += b_loc.segment(e0, ne).template cast<HScalar>();
  const MatX<Scalar> H_ee =
      H_loc_lower.block(e0, e0, ne, ne).template selfadjointView<Eigen::Lower>();
  H.block(oe, oe, ne, ne) += H_ee.template cast<HScalar>();
  for (size_t j = 0; j < map.rcs_offset.size(); ++j) {
    const int oj = map.rcs_offset[j];
    const auto block =
        H_loc_lower.block(e0, static_cast<int>(j) * pd, ne, pd).template cast<HScalar>();
    H.block(oe, oj, ne, pd) += block;
    H.block(oj, oe, pd, ne) += block.transpose();
  }
}

template <typename Scalar, typename HScalar>
void scatterReduced(const PoseBlockMap& map, const MatX<Scalar>& H_loc_lower,
                    const VecX<Scalar>& b_loc, MatX<HScalar>& H, VecX<HScalar>& b) {
  if (map.pose_dim == 6) {
    scatterReducedBlocks<6>(map, H_loc_lower, b_loc, H, b);
  } else {
    scatterReducedBlocks<Eigen::Dynamic>(map, H_loc_lower, b_loc, H, b);
  }
  if (map.extra_cols > 0) scatterReducedExtra(map, H_loc_lower, b_loc, H, b);
}

// The landmark's local pose increment gathered into a per-thread buffer that keeps its capacity
// (no allocation per landmark and LM trial once warm).
template <typename Scalar>
Eigen::Map<const VecX<Scalar>> gatherLocalScratch(const PoseBlockMap& map,
                                                  const VecX<Scalar>& delta_rcs) {
  thread_local std::vector<Scalar> buffer;
  const int pd = map.pose_dim;
  buffer.resize(static_cast<size_t>(map.localCols()));
  for (size_t j = 0; j < map.rcs_offset.size(); ++j) {
    for (int i = 0; i < pd; ++i) buffer[j * pd + i] = delta_rcs[map.rcs_offset[j] + i];
  }
  const size_t e0 = static_cast<size_t>(map.poseCols());
  for (int i = 0; i < map.extra_cols; ++i) buffer[e0 + i] = delta_rcs[map.extra_rcs_offset + i];
  return Eigen::Map<const VecX<Scalar>>(buffer.data(), map.localCols());
}

}  // namespace marglab::landmark_block_detail
