// Flat QR marginalization against independent computations: the long-double SVD pseudo-Schur
// reference (paper eqs. 22–25), SVD numerical rank, Eigen's Householder QR, and the minimum-norm
// property of §4.3.3 / Theorem 2.

#include <Eigen/QR>
#include <Eigen/SVD>

#include "core/linalg/flat_qr.h"
#include "core/linalg/verify_problems.h"
#include "linalg/linalg_test_util.h"

namespace marglab {
namespace {

using test::eps;
using test::relError;

template <typename Scalar>
class FlatQrTest : public ::testing::Test {};
TYPED_TEST_SUITE(FlatQrTest, test::Scalars, test::ScalarName);

template <typename Scalar>
MatX<Scalar> stacked(const TestProblem& problem) {
  const int n = static_cast<int>(problem.J.cols());
  MatX<Scalar> A(problem.J.rows(), n + 1);
  A.leftCols(n) = problem.J.cast<Scalar>();
  A.col(n) = problem.r.cast<Scalar>();
  return A;
}

// R̃ᵀR̃ = H̃ and R̃ᵀr̃ = b̃ of the pseudo-Schur complement, on well-separated ranks.
template <typename Scalar>
void expectMatchesReference(const ProblemSpec& spec) {
  const TestProblem problem = makeProblem(spec);
  const MatX<Scalar> A = stacked<Scalar>(problem);
  const int n = static_cast<int>(problem.J.cols());
  const PseudoSchurReference ref =
      pseudoSchurReference(A.leftCols(n).template cast<double>(), A.col(n).template cast<double>(),
                           spec.n_marg, std::sqrt(eps<Scalar>()));
  ASSERT_FALSE(ref.rank_marg_ambiguous || ref.rank_total_ambiguous);
  const ErrorTolerances tol = errorTolerances(ref, n + 1, eps<Scalar>());

  const FlatQrMarginalization<Scalar> qr = flatQrMarginalize<Scalar>(A, spec.n_marg);
  ASSERT_TRUE(qr.status.ok()) << qr.status.toString();
  EXPECT_EQ(qr.marg_rank, ref.rank_marg);
  EXPECT_EQ(qr.total_rank, ref.rank_total);
  EXPECT_EQ(qr.prior.J.rows(), std::max(1, ref.rank_total - ref.rank_marg));
  const MatXd R = qr.prior.J.template cast<double>();
  const VecXd r = qr.prior.r.template cast<double>();
  EXPECT_LE(relError(R.transpose() * R, ref.H_tilde), tol.H_qr);
  EXPECT_LE(relError(R.transpose() * r, ref.b_tilde), tol.b_qr);
}

TYPED_TEST(FlatQrTest, FullRankPriorIsSchurComplement) {
  expectMatchesReference<TypeParam>({ProblemKind::kFullRank, 40, 6, 12, 0, 1.0, 11});
  expectMatchesReference<TypeParam>({ProblemKind::kFullRank, 30, 15, 15, 0, 1.0, 12});
}

TYPED_TEST(FlatQrTest, RankDeficientMargPriorIsPseudoSchurComplement) {
  expectMatchesReference<TypeParam>({ProblemKind::kRankDeficientMarg, 40, 6, 12, 1, 1.0, 21});
  expectMatchesReference<TypeParam>({ProblemKind::kRankDeficientMarg, 60, 15, 20, 5, 1.0, 22});
}

TYPED_TEST(FlatQrTest, CoupledRankDeficiencyPriorIsPseudoSchurComplement) {
  expectMatchesReference<TypeParam>({ProblemKind::kCoupledRankDeficiency, 40, 6, 12, 0, 1.0, 31});
}

TYPED_TEST(FlatQrTest, IllConditionedPriorWithinConditionBound) {
  expectMatchesReference<TypeParam>({ProblemKind::kIllConditioned, 60, 9, 21, 0, 1e2, 41});
}

TYPED_TEST(FlatQrTest, RevealedRankEqualsSvdRank) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(7);
  for (int rank : {1, 3, 7, 10, 12}) {
    const MatXd J =
        test::randomGaussian(rng, 30, rank) * test::randomGaussian(rng, rank, 12) / 10.0;
    MatX<Scalar> A = MatX<Scalar>::Zero(30, 13);
    A.leftCols(12) = J.cast<Scalar>();
    Eigen::JacobiSVD<MatXd> svd(A.leftCols(12).template cast<double>());
    const auto& s = svd.singularValues();
    const int svd_rank = static_cast<int>((s.array() > std::sqrt(eps<Scalar>()) * s[0]).count());
    const FlatQrInfo info = flatQrInPlace<Scalar>(A, 12, 0, {});
    EXPECT_EQ(info.rank, svd_rank) << "constructed rank " << rank;
    EXPECT_EQ(svd_rank, rank);
  }
}

TYPED_TEST(FlatQrTest, FullRankIsPlainHouseholderQr) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(8);
  const MatX<Scalar> J = (test::randomGaussian(rng, 25, 10) / 5.0).cast<Scalar>();
  MatX<Scalar> A = J;
  const FlatQrInfo info = flatQrInPlace<Scalar>(A, 10, 0, {});
  ASSERT_EQ(info.rank, 10);
  const Eigen::HouseholderQR<MatX<Scalar>> qr(J);
  const MatX<Scalar> R_eigen = qr.matrixQR().template triangularView<Eigen::Upper>();
  // Same reflections, same sign convention: equal up to rounding of the same operations.
  EXPECT_LE(relError(A, R_eigen), 10 * 25 * eps<Scalar>());
  for (int k = 0; k < 10; ++k) EXPECT_EQ(info.pivot_row[k], k);
}

TYPED_TEST(FlatQrTest, StaircaseNeverRisesByMoreThanOneRow) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(9);
  MatXd J = test::randomGaussian(rng, 20, 12) / 4.0;
  // Columns 2, 3 and 7 depend on earlier columns; column 9 is zero.
  J.col(2) = J.col(0) - 0.5 * J.col(1);
  J.col(3) = 2.0 * J.col(1);
  J.col(7) = J.leftCols(7) * VecXd::LinSpaced(7, -1.0, 1.0);
  J.col(9).setZero();
  MatX<Scalar> A = J.cast<Scalar>();
  const FlatQrInfo info = flatQrInPlace<Scalar>(A, 12, 5, {});
  EXPECT_EQ(info.rank, 8);
  EXPECT_EQ(info.rank_prefix, 3);
  int next_row = 0;
  for (int k = 0; k < 12; ++k) {
    const bool dependent = (k == 2 || k == 3 || k == 7 || k == 9);
    if (dependent) {
      EXPECT_EQ(info.pivot_row[k], -1) << "column " << k;
    } else {
      EXPECT_EQ(info.pivot_row[k], next_row++) << "column " << k;
    }
    // Below the staircase everything is an exact zero.
    for (int i = next_row; i < A.rows(); ++i) EXPECT_EQ(A(i, k), Scalar(0)) << i << "," << k;
  }
  // Still a QR decomposition: RᵀR = JᵀJ.
  const MatXd R = A.template cast<double>();
  const MatXd Jd = J.cast<Scalar>().template cast<double>();
  EXPECT_LE(relError(R.transpose() * R, Jd.transpose() * Jd), 100 * 20 * eps<Scalar>());
}

TYPED_TEST(FlatQrTest, RelativeThresholdIsScaleInvariantPerColumn) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(10);
  MatXd J = test::randomGaussian(rng, 20, 6);
  J.col(4) = J.col(0) + J.col(1);
  J.col(5) *= 1e-6;  // tiny but independent: absolute √ε would drop it in float
  FlatQrOptions<Scalar> relative;
  relative.mode = RankThresholdMode::kRelative;
  MatX<Scalar> A = J.cast<Scalar>();
  EXPECT_EQ(flatQrInPlace<Scalar>(A, 6, 0, relative).rank, 5);
  A = J.cast<Scalar>();
  FlatQrOptions<Scalar> absolute;
  const int expected_absolute_rank = std::is_same_v<Scalar, float> ? 4 : 5;
  EXPECT_EQ(flatQrInPlace<Scalar>(A, 6, 0, absolute).rank, expected_absolute_rank);
  const auto result = flatQrMarginalize<Scalar>(MatX<Scalar>::Zero(5, 4), 1, relative);
  EXPECT_EQ(result.mode, RankThresholdMode::kRelative);
  EXPECT_EQ(result.total_rank, 0);
  EXPECT_EQ(result.prior.J.rows(), 1);  // an empty prior keeps one zero row
}

TYPED_TEST(FlatQrTest, NonFiniteInputIsAStatus) {
  using Scalar = TypeParam;
  MatX<Scalar> A = MatX<Scalar>::Identity(6, 5);
  A(2, 1) = std::numeric_limits<Scalar>::quiet_NaN();
  const auto result = flatQrMarginalize<Scalar>(A, 2);
  EXPECT_EQ(result.status.code(), Status::Code::kNotFinite);
}

// Theorem 2 / §4.3.3: if rank(J_μ) + rank([J_κ J_u]) = rank(J) (eq. 26), solving the reduced
// system built from the flat-QR prior with a minimum-norm solver, then back-substituting
// Δx_μ = −H_μμ⁺(b_μ + H_μκ Δx_κ), gives the minimum-norm solution −J⁺r of the whole system.
TEST(FlatQrMinimumNorm, ReducedSolutionIsMinimumNormSolution) {
  std::mt19937_64 rng(11);
  const int n_mu = 5, n_k = 6, n_u = 4, rank_mu = 3;
  const int n = n_mu + n_k + n_u;
  // Rows 0..29 involve μ and κ; rows 30..49 involve κ and u only (the "μ̄" residuals).
  MatXd J = MatXd::Zero(50, n);
  J.block(0, 0, 30, n_mu) =
      test::randomGaussian(rng, 30, rank_mu) * test::randomGaussian(rng, rank_mu, n_mu) / 10.0;
  J.block(0, n_mu, 30, n_k) = test::randomGaussian(rng, 30, n_k) / 5.0;
  J.block(30, n_mu, 20, n_k + n_u) = test::randomGaussian(rng, 20, n_k + n_u) / 5.0;
  const VecXd r = test::randomGaussian(rng, 50, 1);

  Eigen::JacobiSVD<MatXd> svd_J(J, Eigen::ComputeThinU | Eigen::ComputeThinV);
  svd_J.setThreshold(1e-10);
  Eigen::JacobiSVD<MatXd> svd_mu(J.leftCols(n_mu));
  svd_mu.setThreshold(1e-10);
  Eigen::JacobiSVD<MatXd> svd_rest(J.rightCols(n_k + n_u));
  svd_rest.setThreshold(1e-10);
  ASSERT_EQ(svd_mu.rank() + svd_rest.rank(), svd_J.rank());  // eq. 26 holds
  const VecXd dx_tot = -svd_J.solve(r);                      // −J⁺r, the minimum-norm solution

  // Marginalize μ from the residuals that involve it.
  MatXd A(30, n_mu + n_k + 1);
  A << J.block(0, 0, 30, n_mu + n_k), r.head(30);
  const auto marg = flatQrMarginalize<double>(A, n_mu);
  ASSERT_TRUE(marg.status.ok());
  EXPECT_EQ(marg.marg_rank, rank_mu);

  // Reduced system over (κ, u): the prior rows plus the μ̄ residuals, solved minimum-norm.
  const int prior_rows = static_cast<int>(marg.prior.J.rows());
  MatXd J_red = MatXd::Zero(prior_rows + 20, n_k + n_u);
  VecXd r_red(prior_rows + 20);
  J_red.topLeftCorner(prior_rows, n_k) = marg.prior.J;
  J_red.bottomRows(20) = J.block(30, n_mu, 20, n_k + n_u);
  r_red << marg.prior.r, r.tail(20);
  Eigen::JacobiSVD<MatXd> svd_red(J_red, Eigen::ComputeThinU | Eigen::ComputeThinV);
  svd_red.setThreshold(1e-10);
  const VecXd dx_red = -svd_red.solve(r_red);
  EXPECT_LE(relError(dx_red, dx_tot.tail(n_k + n_u)), 1e-10);

  // Back-substitution for μ with the pseudo-inverse of H_μμ.
  const MatXd J_mu = J.block(0, 0, 30, n_mu);
  const MatXd H_mm = J_mu.transpose() * J_mu;
  const MatXd H_mk = J_mu.transpose() * J.block(0, n_mu, 30, n_k);
  const VecXd b_m = J_mu.transpose() * r.head(30);
  Eigen::JacobiSVD<MatXd> svd_H(H_mm, Eigen::ComputeFullU | Eigen::ComputeFullV);
  svd_H.setThreshold(1e-10);
  const VecXd dx_mu = -svd_H.solve(b_m + H_mk * dx_red.head(n_k));
  EXPECT_LE(relError(dx_mu, dx_tot.head(n_mu)), 1e-10);
}

}  // namespace
}  // namespace marglab
