// The Schur-complement landmark elimination (landmark_block.h); compiled per ISA like the
// nullspace one (core/isa_kernels.cmake).
#include <Eigen/Cholesky>

#include "core/common/scalar.h"
#include "core/linalg/landmark_block.h"
#include "core/linalg/landmark_block_common.h"

namespace marglab {

using landmark_block_detail::checkInput;
using landmark_block_detail::gatherLocalScratch;
using landmark_block_detail::scatterReduced;

template <typename Scalar>
Status LandmarkBlockSc<Scalar>::setFromJacobians(const MatX<Scalar>& J_p,
                                                 const Mat<Scalar, Eigen::Dynamic, 3>& J_l,
                                                 const VecX<Scalar>& r, PoseBlockMap map) {
  Status status = checkInput(J_p, J_l, r, map);
  if (!status.ok()) return status;
  map_ = std::move(map);
  // Lower triangle only: the symmetric rank update halves the flops of the full product.
  H_pp_.setZero(J_p.cols(), J_p.cols());
  // Eigen's rank update of an empty J_p binds a reference to its null data (UBSan, §11).
  if (J_p.size() > 0) H_pp_.template selfadjointView<Eigen::Lower>().rankUpdate(J_p.transpose());
  H_pl_ = J_p.transpose() * J_l;
  H_ll_ = J_l.transpose() * J_l;
  b_p_ = J_p.transpose() * r;
  b_l_ = J_l.transpose() * r;
  return Status::Ok();
}

template <typename Scalar>
Status LandmarkBlockSc<Scalar>::dampedFactor(Eigen::LLT<Mat3<Scalar>>* llt) const {
  Mat3<Scalar> H_ll = H_ll_;
  H_ll.diagonal() += damping_;
  llt->compute(H_ll);
  if (llt->info() != Eigen::Success || !llt->matrixLLT().allFinite()) {
    return Status::Error(Status::Code::kRankDeficient,
                         "landmark Schur complement: H_ll is not positive definite");
  }
  return Status::Ok();
}

template <typename Scalar>
template <typename HScalar>
Status LandmarkBlockSc<Scalar>::addToReducedSystem(MatX<HScalar>& H, VecX<HScalar>& b) const {
  Eigen::LLT<Mat3<Scalar>> llt;
  Status status = dampedFactor(&llt);
  if (!status.ok()) return status;
  // No pose block, nothing to add (Eigen's rank update of an empty M binds a null reference).
  if (H_pl_.rows() == 0) return Status::Ok();
  // H_pl H_ll⁻¹ H_lp = MᵀM with M = L⁻¹ H_lp, H_ll = L Lᵀ.
  const Mat<Scalar, 3, Eigen::Dynamic> M =
      llt.matrixL().solve(Mat<Scalar, 3, Eigen::Dynamic>(H_pl_.transpose()));
  MatX<Scalar> H_loc = H_pp_;
  H_loc.template selfadjointView<Eigen::Lower>().rankUpdate(M.transpose(), Scalar(-1));
  const VecX<Scalar> b_loc = b_p_ - M.transpose() * llt.matrixL().solve(b_l_);
  scatterReduced(map_, H_loc, b_loc, H, b);
  return Status::Ok();
}

template <typename Scalar>
Status LandmarkBlockSc<Scalar>::backSubstitute(const VecX<Scalar>& delta_rcs,
                                               Vec3<Scalar>* delta_l) const {
  Eigen::LLT<Mat3<Scalar>> llt;
  Status status = dampedFactor(&llt);
  if (!status.ok()) return status;
  const auto delta_p = gatherLocalScratch(map_, delta_rcs);
  *delta_l = -llt.solve(b_l_ + H_pl_.transpose() * delta_p);
  if (!delta_l->allFinite()) {
    return Status::Error(Status::Code::kNotFinite, "landmark back-substitution: non-finite step");
  }
  return Status::Ok();
}

template <typename Scalar>
Scalar LandmarkBlockSc<Scalar>::linearizedCostChange(const VecX<Scalar>& delta_rcs,
                                                     const Vec3<Scalar>& delta_l) const {
  const auto delta_p = gatherLocalScratch(map_, delta_rcs);
  const Scalar quadratic = delta_p.dot(H_pp_.template selfadjointView<Eigen::Lower>() * delta_p) +
                           Scalar(2) * delta_p.dot(H_pl_ * delta_l) + delta_l.dot(H_ll_ * delta_l);
  return b_p_.dot(delta_p) + b_l_.dot(delta_l) + Scalar(0.5) * quadratic;
}

#define MARGLAB_INST(S)              \
  template class LandmarkBlockSc<S>; \
  template Status LandmarkBlockSc<S>::addToReducedSystem<S>(MatX<S>&, VecX<S>&) const;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
