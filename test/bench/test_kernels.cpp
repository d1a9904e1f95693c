// The hand-written landmark-block kernels against independent computations: the in-place
// (row-major) Householder QR of the landmark columns against Eigen's HouseholderQR (R up to row
// signs, the projection onto the left nullspace of J_l through an SVD), in f32 and f64, including a
// rank-deficient J_l.

#include <gtest/gtest.h>

#include <Eigen/QR>
#include <Eigen/SVD>
#include <random>

#include "core/linalg/landmark_block.h"

namespace marglab {
namespace {

template <typename T>
class KernelTest : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
struct ScalarName {
  template <typename T>
  static std::string GetName(int) {
    return std::is_same_v<T, float> ? "f32" : "f64";
  }
};
TYPED_TEST_SUITE(KernelTest, Scalars, ScalarName);

// [J_p | J_l | r] with m rows, n_p pose columns; J_l of rank `rank_l`.
MatXd randomBlock(int m, int n_p, int rank_l, std::mt19937& rng) {
  std::normal_distribution<double> n;
  MatXd A(m, n_p + 4);
  for (int i = 0; i < A.size(); ++i) A.data()[i] = n(rng);
  if (rank_l < 3) {
    const MatXd basis = A.block(0, n_p, m, rank_l);
    MatXd mix(rank_l, 3 - rank_l);
    for (int i = 0; i < mix.size(); ++i) mix.data()[i] = n(rng);
    A.block(0, n_p + rank_l, m, 3 - rank_l) = basis * mix;
  }
  return A;
}

TYPED_TEST(KernelTest, HouseholderLandmarkColumnsIsAnOrthogonalTriangularization) {
  using S = TypeParam;
  std::mt19937 rng(3);
  // Pose blocks 0 .. 11: every split of the row into the kernel's column chunks.
  for (int trial = 0; trial < 48; ++trial) {
    const int n_p = 6 * (trial % 12);
    const int m = 4 + trial % 20;
    const int rank_l = trial % 5 == 4 ? 2 : 3;
    const MatXd A = randomBlock(m, n_p, rank_l, rng);
    Eigen::Matrix<S, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> B = A.cast<S>();
    householderLandmarkColumns<S>(B.data(), B.cols(), m, n_p);
    const MatXd Bd = B.template cast<double>();
    const double eps = std::numeric_limits<S>::epsilon();
    const double scale = A.norm();
    // Zeros below the diagonal of the landmark columns.
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(Bd.col(n_p + k).tail(m - k - 1).norm(), 0.0);
    }
    // Orthogonal: column norms and inner products preserved (AᵀA = BᵀB).
    const MatXd G = A.transpose() * A, GB = Bd.transpose() * Bd;
    EXPECT_LE((G - GB).norm(), 50 * m * eps * scale * scale) << "trial " << trial;
    // R1 = the R of J_l up to row signs.
    if (rank_l == 3) {
      const Eigen::HouseholderQR<MatXd> qr(A.block(0, n_p, m, 3));
      const Mat3<double> R = qr.matrixQR().topRows(3).triangularView<Eigen::Upper>();
      const Mat3<double> R1 = Bd.block(0, n_p, 3, 3);
      for (int k = 0; k < 3; ++k) {
        const double sign = (R(k, k) >= 0) == (R1(k, k) >= 0) ? 1 : -1;
        EXPECT_LE((R.row(k) - sign * R1.row(k)).norm(), 50 * m * eps * scale) << trial;
      }
      // The rows below 3 are the projection onto the left nullspace of J_l (rank 3):
      // (Q2ᵀX)ᵀ(Q2ᵀX) = Xᵀ(I − U Uᵀ)X for X = [J_p r], U from the SVD of J_l.
      const Eigen::JacobiSVD<MatXd> svd(A.block(0, n_p, m, 3), Eigen::ComputeThinU);
      const MatXd U = svd.matrixU();
      MatXd X(m, n_p + 1);
      X << A.leftCols(n_p), A.col(n_p + 3);
      const MatXd P = X.transpose() * X - (U.transpose() * X).transpose() * (U.transpose() * X);
      MatXd Y(m - 3, n_p + 1);
      Y << Bd.block(3, 0, m - 3, n_p), Bd.col(n_p + 3).segment(3, m - 3);
      const double kappa = svd.singularValues()(0) / svd.singularValues()(2);
      EXPECT_LE((Y.transpose() * Y - P).norm(), 50 * m * kappa * eps * scale * scale) << trial;
    }
  }
}

}  // namespace
}  // namespace marglab
