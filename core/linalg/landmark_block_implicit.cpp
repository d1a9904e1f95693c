#include "core/linalg/landmark_block_implicit.h"

#include <fmt/core.h>

#include <Eigen/Householder>

#include "core/common/scalar.h"

namespace marglab {
namespace {

// H = I − τ v vᵀ (v(k) = 1, v's tail stored below row k of column k of W) applied from the left to
// column c of W or of Q, rows k .. m − 1.
template <typename Scalar, int Rows, typename Column>
void reflect(const Mat<Scalar, Rows, 3>& W, Eigen::Index k, Scalar tau, Column&& col) {
  const Eigen::Index m = W.rows();
  Scalar w = col[k];
  for (Eigen::Index i = k + 1; i < m; ++i) w += W(i, k) * col[i];
  w *= tau;
  col[k] -= w;
  for (Eigen::Index i = k + 1; i < m; ++i) col[i] -= W(i, k) * w;
}

// Thin Householder QR of the m × 3 matrix in W (overwritten by the reflectors): Q (m × 3, thin)
// and R (upper). Written out rather than Eigen's HouseholderQR, whose reflector products on nested
// dynamic blocks allocate a temporary per column (a malloc per landmark and linearization).
template <typename Scalar, int Rows>
void thinQr(Mat<Scalar, Rows, 3>* W, Mat<Scalar, Rows, 3>* Q, Mat3<Scalar>* R) {
  const Eigen::Index m = W->rows();
  Vec3<Scalar> tau;
  R->setZero();
  for (Eigen::Index k = 0; k < 3; ++k) {
    Scalar beta;
    auto tail = W->col(k).tail(m - k);
    tail.makeHouseholderInPlace(tau[k], beta);  // v's tail below row k; R(k, k) = beta
    (*R)(k, k) = beta;
    for (Eigen::Index c = k + 1; c < 3; ++c) {
      reflect(*W, k, tau[k], W->col(c));
      (*R)(k, c) = (*W)(k, c);
    }
  }
  Q->setIdentity(m, 3);
  for (Eigen::Index k = 2; k >= 0; --k) {
    for (Eigen::Index c = 0; c < 3; ++c) reflect(*W, k, tau[k], Q->col(c));
  }
}

}  // namespace

template <typename Scalar, int PoseDim>
Status LandmarkBlockNsImplicit<Scalar, PoseDim>::setFromJacobians(
    const Eigen::Ref<const Mat<Scalar, Eigen::Dynamic, PoseDim>>& J_obs,
    const Eigen::Ref<const Mat<Scalar, Eigen::Dynamic, 3>>& J_l,
    const Eigen::Ref<const VecX<Scalar>>& r, const PoseBlockMap& map) {
  const Eigen::Index m = J_l.rows();
  if (map.pose_dim != PoseDim || m < 4 ||
      m != 2 * static_cast<Eigen::Index>(map.rcs_offset.size()) || J_obs.rows() != m ||
      r.size() != m) {
    return Status::Error(Status::Code::kInvalidArgument,
                         fmt::format("landmark block: J_obs {}x{}, J_l {}x3, r {} with {} pose "
                                     "blocks of {} (needs two rows per block, ≥ 2 blocks of {})",
                                     J_obs.rows(), J_obs.cols(), m, r.size(), map.rcs_offset.size(),
                                     map.pose_dim, PoseDim));
  }
  if (!J_l.allFinite() || !r.allFinite()) {
    return Status::Error(Status::Code::kNotFinite,
                         "landmark block: non-finite Jacobian or residual");
  }
  map_ = map;  // the same cameras at every linearization: the storage is kept
  J_obs_ = J_obs;
  J_l_ = J_l;
  r_ = r;
  H_ll_diagonal_ = J_l.colwise().squaredNorm().transpose();
  reflectors_ = J_l;
  thinQr(&reflectors_, &Q1_, &R1_undamped_);
  setLandmarkDamping(Vec3<Scalar>::Zero());
  return Status::Ok();
}

// [R1; diag(√d)] = G [R1ᵈ; 0] by a 6 × 3 Householder QR; the damped thin factor's top rows are
// Q1 G(0:3, 0:3).
template <typename Scalar, int PoseDim>
void LandmarkBlockNsImplicit<Scalar, PoseDim>::setLandmarkDamping(const Vec3<Scalar>& d) {
  if ((d.array() <= Scalar(0)).all()) {
    U_ = Q1_;
    R1_ = R1_undamped_;
  } else {
    Mat<Scalar, 6, 3> stack, G;
    stack.template topRows<3>() = R1_undamped_;
    stack.template bottomRows<3>() = d.cwiseMax(Scalar(0)).cwiseSqrt().asDiagonal();
    thinQr(&stack, &G, &R1_);
    U_ = Q1_.lazyProduct(G.template topRows<3>());  // m × 3 × 3: no GEMM blocking
  }
  Ut_r_.noalias() = U_.transpose() * r_;
}

template <typename Scalar, int PoseDim>
void LandmarkBlockNsImplicit<Scalar, PoseDim>::reducedProduct(const VecX<Scalar>& x, Scalar* t,
                                                              Scalar* y) const {
  // Two passes over the observations with fixed-size blocks only (a dynamic 3 × m product costs
  // more in call overhead than in flops at these sizes): t_j = J_j x_j and u = Σ_j U_jᵀ t_j, then
  // y_j = J_jᵀ (t_j − U_j u).
  Vec3<Scalar> u = Vec3<Scalar>::Zero();
  for (int j = 0; j < blocks(); ++j) {
    Eigen::Map<Vec<Scalar, 2>> t_j(t + 2 * j);
    t_j.noalias() =
        J_obs_.template middleRows<2>(2 * j) * x.template segment<PoseDim>(map_.rcs_offset[j]);
    u.noalias() += U_.template middleRows<2>(2 * j).transpose() * t_j;
  }
  for (int j = 0; j < blocks(); ++j) {
    const Vec<Scalar, 2> p_j =
        Eigen::Map<const Vec<Scalar, 2>>(t + 2 * j) - U_.template middleRows<2>(2 * j) * u;
    Eigen::Map<Vec<Scalar, PoseDim>>(y + PoseDim * j).noalias() =
        J_obs_.template middleRows<2>(2 * j).transpose() * p_j;
  }
}

template <typename Scalar, int PoseDim>
void LandmarkBlockNsImplicit<Scalar, PoseDim>::reducedGradient(Scalar* y) const {
  for (int j = 0; j < blocks(); ++j) {
    const Vec<Scalar, 2> p_r =
        r_.template segment<2>(2 * j) - U_.template middleRows<2>(2 * j) * Ut_r_;
    Eigen::Map<Vec<Scalar, PoseDim>>(y + PoseDim * j).noalias() =
        J_obs_.template middleRows<2>(2 * j).transpose() * p_r;
  }
}

template <typename Scalar, int PoseDim>
Mat<Scalar, PoseDim, PoseDim> LandmarkBlockNsImplicit<Scalar, PoseDim>::reducedCameraBlock(
    int j) const {
  const auto J_j = J_obs_.template middleRows<2>(2 * j);
  const Mat<Scalar, 3, PoseDim> A_j = U_.template middleRows<2>(2 * j).transpose().lazyProduct(J_j);
  // Lazy products: fixed sizes this small are faster coefficient-wise than through GEMM.
  return J_j.transpose().lazyProduct(J_j) - A_j.transpose().lazyProduct(A_j);
}

template <typename Scalar, int PoseDim>
Status LandmarkBlockNsImplicit<Scalar, PoseDim>::addToReducedSystem(MatX<Scalar>& H,
                                                                    VecX<Scalar>& b) const {
  if (!landmarkSolvable()) {
    return Status::Error(Status::Code::kRankDeficient,
                         "landmark elimination: R1 is singular (landmark not observable)");
  }
  std::vector<Mat<Scalar, 3, PoseDim>> A(static_cast<size_t>(blocks()));
  for (int j = 0; j < blocks(); ++j) {
    A[j].noalias() =
        U_.template middleRows<2>(2 * j).transpose() * J_obs_.template middleRows<2>(2 * j);
  }
  VecX<Scalar> g(PoseDim * blocks());
  reducedGradient(g.data());
  for (int j = 0; j < blocks(); ++j) {
    const int oj = map_.rcs_offset[j];
    const auto J_j = J_obs_.template middleRows<2>(2 * j);
    H.template block<PoseDim, PoseDim>(oj, oj).noalias() += J_j.transpose() * J_j;
    for (int k = 0; k < blocks(); ++k) {
      H.template block<PoseDim, PoseDim>(oj, map_.rcs_offset[k]).noalias() -=
          A[j].transpose() * A[k];
    }
    b.template segment<PoseDim>(oj) += g.template segment<PoseDim>(PoseDim * j);
  }
  return Status::Ok();
}

template <typename Scalar, int PoseDim>
Status LandmarkBlockNsImplicit<Scalar, PoseDim>::backSubstitute(const VecX<Scalar>& delta_rcs,
                                                                Vec3<Scalar>* delta_l) const {
  if (!landmarkSolvable()) {
    return Status::Error(Status::Code::kRankDeficient,
                         "landmark back-substitution: R1 is singular (landmark not observable)");
  }
  Vec3<Scalar> rhs = Ut_r_;
  for (int j = 0; j < blocks(); ++j) {
    const Vec<Scalar, 2> t_j = J_obs_.template middleRows<2>(2 * j) *
                               delta_rcs.template segment<PoseDim>(map_.rcs_offset[j]);
    rhs.noalias() += U_.template middleRows<2>(2 * j).transpose() * t_j;
  }
  *delta_l = -R1_.template triangularView<Eigen::Upper>().solve(rhs);
  if (!delta_l->allFinite()) {
    return Status::Error(Status::Code::kNotFinite, "landmark back-substitution: non-finite step");
  }
  return Status::Ok();
}

template <typename Scalar, int PoseDim>
Scalar LandmarkBlockNsImplicit<Scalar, PoseDim>::linearizedCostChange(
    const VecX<Scalar>& delta_rcs, const Vec3<Scalar>& delta_l) const {
  Scalar change = 0;
  for (int j = 0; j < blocks(); ++j) {
    const Vec<Scalar, 2> e_j = J_obs_.template middleRows<2>(2 * j) *
                                   delta_rcs.template segment<PoseDim>(map_.rcs_offset[j]) +
                               J_l_.template middleRows<2>(2 * j) * delta_l;
    change += e_j.dot(r_.template segment<2>(2 * j)) + Scalar(0.5) * e_j.squaredNorm();
  }
  return change;
}

#define MARGLAB_INST(S) template class LandmarkBlockNsImplicit<S, 9>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
