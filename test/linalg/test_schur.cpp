// Schur-complement marginalization, pseudo-inverse and LDLT square root against independent
// computations (SVD pseudo-inverse, Moore–Penrose conditions, the long-double reference).

#include <Eigen/QR>
#include <Eigen/SVD>

#include "core/linalg/schur.h"
#include "core/linalg/verify_problems.h"
#include "linalg/linalg_test_util.h"

namespace marglab {
namespace {

using test::eps;
using test::relError;

template <typename Scalar>
class SchurTest : public ::testing::Test {};
TYPED_TEST_SUITE(SchurTest, test::Scalars, test::ScalarName);

TYPED_TEST(SchurTest, PseudoInverseSatisfiesMoorePenroseConditions) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(21);
  for (int rank : {2, 5, 8}) {
    const MatXd B = test::randomGaussian(rng, rank, 8) / 3.0;
    const MatX<Scalar> H = (B.transpose() * B).cast<Scalar>();
    const PseudoInverse<Scalar> pinv = pseudoInverseSelfAdjoint<Scalar>(H);
    EXPECT_EQ(pinv.rank, rank);
    // κ(H restricted to its range) bounds the error of the computed pseudo-inverse.
    Eigen::JacobiSVD<MatXd> svd(H.template cast<double>(),
                                Eigen::ComputeFullU | Eigen::ComputeFullV);
    const auto& s = svd.singularValues();
    const double kappa = s[0] / s[rank - 1];
    const double tol = 100 * 8 * eps<Scalar>() * kappa;
    const MatXd Hd = H.template cast<double>();
    const MatXd P = pinv.H_pinv.template cast<double>();
    EXPECT_LE(relError(Hd * P * Hd, Hd), tol);
    EXPECT_LE(relError(P * Hd * P, P), tol);
    svd.setThreshold(std::sqrt(eps<Scalar>()));
    const MatXd P_svd = svd.solve(MatXd::Identity(8, 8));
    EXPECT_LE(relError(P, P_svd), tol * kappa);
  }
}

// c̃ = −½ b_μᵀ H_μμ⁺ b_μ is the minimum over μ of ½‖J_μ μ + r‖² − ½‖r‖² = −½‖P r‖², P the
// projector onto range(J_μ), computed here by a rank-revealing QR in double — also when J_μ is
// rank deficient.
TYPED_TEST(SchurTest, ConstantIsTheMinimumOverTheMarginalizedVariables) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(23);
  for (int rank : {6, 4}) {
    MatXd J = test::randomGaussian(rng, 30, 10);
    J.leftCols(6) = J.leftCols(rank) * test::randomGaussian(rng, rank, 6);  // rank of J_μ
    const VecXd r = test::randomGaussian(rng, 30, 1);
    const MatX<Scalar> H = (J.transpose() * J).cast<Scalar>();
    const VecX<Scalar> b = (J.transpose() * r).cast<Scalar>();
    const SchurMarginalization<Scalar> sc = schurMarginalize<Scalar>(H, b, 6);
    ASSERT_TRUE(sc.status.ok());
    EXPECT_EQ(sc.marg_rank, rank);
    Eigen::ColPivHouseholderQR<MatXd> qr(J.leftCols(6));
    const MatXd Q = qr.householderQ() * MatXd::Identity(30, qr.rank());
    const double expected = -0.5 * (Q.transpose() * r).squaredNorm();
    Eigen::JacobiSVD<MatXd> svd(J.leftCols(6));
    const double kappa = svd.singularValues()[0] / svd.singularValues()[rank - 1];
    EXPECT_NEAR(static_cast<double>(sc.prior.c), expected,
                100 * test::eps<Scalar>() * kappa * kappa * r.squaredNorm());
  }
}

TYPED_TEST(SchurTest, MatchesPseudoSchurReference) {
  using Scalar = TypeParam;
  for (const ProblemSpec& spec :
       {ProblemSpec{ProblemKind::kFullRank, 40, 6, 12, 0, 1.0, 31},
        ProblemSpec{ProblemKind::kRankDeficientMarg, 40, 6, 12, 2, 1.0, 32},
        ProblemSpec{ProblemKind::kCoupledRankDeficiency, 40, 6, 12, 0, 1.0, 33}}) {
    const TestProblem problem = makeProblem(spec);
    const MatX<Scalar> J = problem.J.cast<Scalar>();
    const VecX<Scalar> r = problem.r.cast<Scalar>();
    const MatX<Scalar> H = J.transpose() * J;
    const VecX<Scalar> b = J.transpose() * r;
    const PseudoSchurReference ref =
        pseudoSchurReference(J.template cast<double>(), r.template cast<double>(), spec.n_marg,
                             std::sqrt(eps<Scalar>()));
    const ErrorTolerances tol = errorTolerances(ref, static_cast<int>(J.cols()) + 1, eps<Scalar>());
    const SchurMarginalization<Scalar> sc = schurMarginalize<Scalar>(H, b, spec.n_marg);
    ASSERT_TRUE(sc.status.ok()) << sc.status.toString();
    EXPECT_EQ(sc.marg_rank, ref.rank_marg) << toString(spec.kind);
    EXPECT_LE(relError(sc.prior.H, ref.H_tilde), tol.H_sc) << toString(spec.kind);
    EXPECT_LE(relError(sc.prior.b, ref.b_tilde), tol.b_sc) << toString(spec.kind);
    EXPECT_LE(relError(sc.prior.H, MatX<Scalar>(sc.prior.H.transpose())), eps<Scalar>());
  }
}

TYPED_TEST(SchurTest, FullRankEqualsExplicitInverseFormula) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(22);
  const MatXd J = test::randomGaussian(rng, 20, 9) / 4.0;
  const VecXd r = test::randomGaussian(rng, 20, 1);
  const MatXd H = J.transpose() * J;
  const VecXd b = J.transpose() * r;
  const MatXd H_mm_inv = H.topLeftCorner(4, 4).inverse();
  const MatXd H_expected =
      H.bottomRightCorner(5, 5) - H.bottomLeftCorner(5, 4) * H_mm_inv * H.topRightCorner(4, 5);
  const VecXd b_expected = b.tail(5) - H.bottomLeftCorner(5, 4) * H_mm_inv * b.head(4);
  const auto sc = schurMarginalize<Scalar>(H.cast<Scalar>(), b.cast<Scalar>(), 4);
  const double kappa = 1.0 / H.topLeftCorner(4, 4).eigenvalues().real().minCoeff() *
                       H.topLeftCorner(4, 4).eigenvalues().real().maxCoeff();
  EXPECT_LE(relError(sc.prior.H, H_expected), 100 * 9 * eps<Scalar>() * kappa);
  EXPECT_LE(relError(sc.prior.b, b_expected), 100 * 9 * eps<Scalar>() * kappa);
}

TYPED_TEST(SchurTest, BadInputIsAStatus) {
  using Scalar = TypeParam;
  MatX<Scalar> H = MatX<Scalar>::Identity(4, 4);
  VecX<Scalar> b = VecX<Scalar>::Zero(4);
  EXPECT_EQ(schurMarginalize<Scalar>(H, b, 5).status.code(), Status::Code::kInvalidArgument);
  H(1, 1) = std::numeric_limits<Scalar>::infinity();
  EXPECT_EQ(schurMarginalize<Scalar>(H, b, 2).status.code(), Status::Code::kNotFinite);
}

TYPED_TEST(SchurTest, LdltSquareRootReproducesHessianAndGradient) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(23);
  for (int rank : {10, 6}) {  // positive definite, then semi-definite with b in range(H)
    const MatXd B = test::randomGaussian(rng, rank, 10) / 3.0;
    const MatXd H = B.transpose() * B;
    const VecXd b = B.transpose() * test::randomGaussian(rng, rank, 1);
    const auto sqrt = hessianToSqrtLdlt<Scalar>(H.cast<Scalar>(), b.cast<Scalar>());
    ASSERT_TRUE(sqrt.status.ok()) << sqrt.status.toString();
    const MatXd J = sqrt.prior.J.template cast<double>();
    const VecXd r = sqrt.prior.r.template cast<double>();
    Eigen::JacobiSVD<MatXd> svd(B);
    const double kappa = svd.singularValues()[0] / svd.singularValues()[rank - 1];
    const double tol = 100 * 10 * eps<Scalar>() * kappa * kappa;
    EXPECT_LE(relError(J.transpose() * J, H), tol) << "rank " << rank;
    EXPECT_LE(relError(J.transpose() * r, b), tol) << "rank " << rank;
    if (rank == 10) {
      EXPECT_EQ(sqrt.rank, 10);
    }
  }
}

TYPED_TEST(SchurTest, LdltSquareRootClampsNegativePivots) {
  using Scalar = TypeParam;
  MatX<Scalar> H = MatX<Scalar>::Zero(3, 3);
  H.diagonal() << Scalar(4), Scalar(-1e-3), Scalar(1);
  const auto sqrt = hessianToSqrtLdlt<Scalar>(H, VecX<Scalar>::Ones(3));
  EXPECT_EQ(sqrt.n_clamped, 1);
  EXPECT_EQ(sqrt.rank, 2);
  const MatX<Scalar> H_psd = sqrt.prior.J.transpose() * sqrt.prior.J;
  EXPECT_NEAR(H_psd(0, 0), 4, 4 * eps<Scalar>());
  EXPECT_EQ(H_psd(1, 1), Scalar(0));
  EXPECT_NEAR(H_psd(2, 2), 1, 4 * eps<Scalar>());
}

// The gauge-exact psd projection (psd axis g): a prior whose exact Hessian has a g-dimensional
// nullspace G (the gauge), rounded to the scalar type — rank deficient, or near-singular with
// information along G far below the scalar's resolution. With the relative pivot floor of
// NumericTraits the LDLT square root J has g zero rows, so an exact g-dimensional nullspace, and an
// SVD of J in double finds it to be span(G) within ε·κ (κ over the observable directions), while
// JᵀJ keeps the observable information. The gauge's pivots come out of the elimination at about
// ε·κ·max D, so the floor n·ε·max D finds them only in a well-conditioned prior (κ here ≈ 10, the
// block-scaled priors of sqp about 1e2 on KITTI; docs/preconditioned_storage.md §4).
TYPED_TEST(SchurTest, LdltGaugeExactFloorKeepsTheNullspace) {
  using Scalar = TypeParam;
  constexpr int n = 15, g = 4;
  std::mt19937_64 rng(29);
  const MatXd G = Eigen::HouseholderQR<MatXd>(test::randomGaussian(rng, n, g)).householderQ() *
                  MatXd::Identity(n, g);
  const MatXd projector = MatXd::Identity(n, n) - G * G.transpose();
  const MatXd B = test::randomGaussian(rng, 4 * n, n) * projector;
  const MatXd H_exact = B.transpose() * B;
  Eigen::JacobiSVD<MatXd> svd_h(H_exact);
  const double kappa = svd_h.singularValues()[0] / svd_h.singularValues()[n - g - 1];
  const double floor = static_cast<double>(NumericTraits<Scalar>::ldltPivotRelativeTolerance(n));
  const double tol = 100 * n * eps<Scalar>() * kappa;
  // Near-singular: information along G at a hundredth of the floor times the smallest diagonal.
  for (double along_gauge : {0.0, 1e-2 * floor * H_exact.diagonal().minCoeff()}) {
    SCOPED_TRACE(along_gauge);
    const MatXd H = H_exact + along_gauge * G * G.transpose();
    const VecXd b = B.transpose() * test::randomGaussian(rng, 4 * n, 1);
    const auto sqrt = hessianToSqrtLdlt<Scalar>(
        H.cast<Scalar>(), b.cast<Scalar>(), NumericTraits<Scalar>::ldltPivotRelativeTolerance(n));
    ASSERT_TRUE(sqrt.status.ok()) << sqrt.status.toString();
    EXPECT_EQ(sqrt.rank, n - g);
    const MatXd J = sqrt.prior.J.template cast<double>();
    EXPECT_EQ((J.rowwise().norm().array() == 0.0).count(), g);  // an exact nullspace
    Eigen::JacobiSVD<MatXd> svd_j(J, Eigen::ComputeFullV);
    // sin of the largest principal angle between J's nullspace and the gauge directions.
    const MatXd null_j = svd_j.matrixV().rightCols(g);
    EXPECT_LE((projector * null_j).norm(), tol);
    EXPECT_LE((J * G).norm() / J.norm(), tol);
    EXPECT_LE(relError(J.transpose() * J, H_exact), tol);
  }
}

// A floor of 0 is the negative clamp bit for bit (every storage without psd projection g); a
// positive pivot below floor · max D is clamped too.
TYPED_TEST(SchurTest, LdltPivotFloorIsRelativeToTheLargestPivot) {
  using Scalar = TypeParam;
  MatX<Scalar> H = MatX<Scalar>::Zero(3, 3);
  H.diagonal() << Scalar(4), Scalar(-1e-3), Scalar(1);
  const auto plain = hessianToSqrtLdlt<Scalar>(H, VecX<Scalar>::Ones(3));
  const auto floored = hessianToSqrtLdlt<Scalar>(H, VecX<Scalar>::Ones(3), Scalar(0));
  EXPECT_EQ(plain.prior.J, floored.prior.J);
  H(1, 1) = Scalar(1e-3);
  EXPECT_EQ(hessianToSqrtLdlt<Scalar>(H, VecX<Scalar>::Ones(3), Scalar(1e-3)).n_clamped, 1);
  EXPECT_EQ(hessianToSqrtLdlt<Scalar>(H, VecX<Scalar>::Ones(3), Scalar(1e-4)).n_clamped, 0);
}

}  // namespace
}  // namespace marglab
