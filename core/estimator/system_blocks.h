#pragma once
// Block bookkeeping between the window's factors and a linear system over window variables: a
// factor's rows span a few variables (VarKey) at offsets of its own Jacobian; the system orders
// all variables by a ColumnMap (window.h). Shared by the linearization and the marginalizers.

#include <utility>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/estimator/marg_prior.h"
#include "core/estimator/window.h"
#include "core/linalg/landmark_block.h"

namespace marglab {

using BlockLayout = std::vector<std::pair<VarKey, int>>;  // variable → offset in the factor

// Adds H_blocks / b_blocks, laid out as `vars`, to a system with columns column_of.
template <typename Scalar>
void scatterBlocks(const BlockLayout& vars, const MatX<Scalar>& H_blocks,
                   const VecX<Scalar>& b_blocks, const ColumnMap& column_of, MatX<Scalar>& H,
                   VecX<Scalar>& b) {
  for (const auto& [var_i, off_i] : vars) {
    const int ci = column_of.at(var_i);
    const int ni = stateBlockDim(var_i.block);
    b.segment(ci, ni) += b_blocks.segment(off_i, ni);
    for (const auto& [var_j, off_j] : vars) {
      const int nj = stateBlockDim(var_j.block);
      H.block(ci, column_of.at(var_j), ni, nj) += H_blocks.block(off_i, off_j, ni, nj);
    }
  }
}

// Adds JᵀJ, Jᵀr of a factor's rows to a system with columns column_of.
template <typename Scalar, typename Rows>
void addRows(const Rows& rows, const BlockLayout& vars, const ColumnMap& column_of, MatX<Scalar>& H,
             VecX<Scalar>& b) {
  const MatX<Scalar> H_rows = rows.J.transpose() * rows.J;
  const VecX<Scalar> b_rows = rows.J.transpose() * rows.r;
  scatterBlocks(vars, H_rows, b_rows, column_of, H, b);
}

// Gathers the entries of a system vector for a layout of blocks.
template <typename Scalar>
VecX<Scalar> gatherBlocks(const BlockLayout& vars, int size, const VecX<Scalar>& x,
                          const ColumnMap& column_of) {
  VecX<Scalar> out(size);
  for (const auto& [var, offset] : vars) {
    const int n = stateBlockDim(var.block);
    out.segment(offset, n) = x.segment(column_of.at(var), n);
  }
  return out;
}

template <typename Scalar>
BlockLayout priorVars(const MargPrior<Scalar>& prior) {
  BlockLayout vars;
  for (const auto& block : prior.blocks) vars.emplace_back(block.var, block.offset);
  return vars;
}

// Adds the prior's Hessian and gradient at δ to a system with columns column_of.
template <typename Scalar>
void addPrior(const MargPrior<Scalar>& prior, const VecX<Scalar>& delta, const ColumnMap& column_of,
              MatX<Scalar>& H, VecX<Scalar>& b) {
  MatX<Scalar> Hp;
  VecX<Scalar> bp;
  prior.linearize(delta, &Hp, &bp);
  scatterBlocks(priorVars(prior), Hp, bp, column_of, H, b);
}

// A landmark's pose blocks in a system with columns column_of.
template <typename Scalar>
PoseBlockMap blockMap(const LandmarkJacobians<Scalar>& lin, const ColumnMap& column_of) {
  PoseBlockMap map;
  map.pose_dim = kPoseDim;
  for (int64_t f : lin.frames) map.rcs_offset.push_back(column_of.at({f, StateBlock::kPose}));
  if (lin.stereo_offset) {
    map.extra_cols = kStereoOffsetDim;
    map.extra_rcs_offset = column_of.at(kStereoOffsetVar);
  }
  return map;
}

}  // namespace marglab
