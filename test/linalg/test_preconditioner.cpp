// Block-diagonal preconditioning (core/linalg/preconditioner.h) against independent double
// computations: the scaled matrix maps back to the same H, a preconditioned LDLT solve and a
// preconditioned Schur complement reproduce the double-precision reference within
// ε · κ(scaled H), the scaling lowers the condition number of an ill-scaled Hessian, and a
// singular or non-finite system is a status, not a crash.

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

#include "core/linalg/preconditioner.h"
#include "core/linalg/rcs_solve.h"
#include "core/linalg/schur.h"
#include "linalg/linalg_test_util.h"

namespace marglab {
namespace {

using test::eps;
using test::relError;

template <typename Scalar>
class PreconditionerTest : public ::testing::Test {};
TYPED_TEST_SUITE(PreconditionerTest, test::Scalars, test::ScalarName);

// An ill-scaled VIO-like Hessian H = JᵀJ over `frames` × [position, rotation, velocity, bias]
// (3 columns each): rotation columns carry a lever arm of 1e4 m (a world-frame rotation increment
// seen from positions 1e4 m from the origin), velocities 1e-1, biases 1e4 (information 1e8 of a
// small random walk); within each quantity a random 3×3 mixing of condition ≈ 10.
MatXd illScaledHessian(std::mt19937_64& rng, int frames) {
  const int n = 12 * frames;
  MatXd J = test::randomGaussian(rng, 2 * n, n);
  const double unit[4] = {1.0, 1e4, 1e-1, 1e4};
  for (int k = 0; k < n / 3; ++k) {
    const MatXd U = Eigen::HouseholderQR<MatXd>(test::randomGaussian(rng, 3, 3)).householderQ();
    const Eigen::Matrix3d mix = U * Eigen::Vector3d(1.0, 3.0, 10.0).asDiagonal() * U.transpose();
    J.middleCols(3 * k, 3) = unit[k % 4] * J.middleCols(3 * k, 3) * mix;
  }
  return J.transpose() * J;
}

double conditionNumber(const MatXd& H) {
  const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<MatXd>(H).eigenvalues();
  return ev.maxCoeff() / ev.minCoeff();
}

// Pᵀ H P of the Scalar scaling, evaluated in double.
template <typename Scalar>
MatXd scaledInDouble(const BlockScaling<Scalar>& P, const MatXd& H) {
  const int n = static_cast<int>(H.rows());
  MatXd Pd = MatXd::Zero(n, n);
  for (int j = 0; j < n; ++j) {
    VecX<Scalar> e = VecX<Scalar>::Zero(n);
    e[j] = 1;
    Pd.col(j) = P.toDelta(e).template cast<double>();
  }
  return Pd.transpose() * H * Pd;
}

TYPED_TEST(PreconditionerTest, ScalingLowersTheConditionOfAnIllScaledHessian) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(31);
  const MatXd H = illScaledHessian(rng, 2);
  const double kappa = conditionNumber(H);
  ASSERT_GT(kappa, 1e12);
  const MatX<Scalar> H_s = H.cast<Scalar>();
  const double kappa_jacobi = conditionNumber(
      scaledInDouble(BlockScaling<Scalar>::fromHessian(H_s, Preconditioning::kJacobi), H));
  const double kappa_block = conditionNumber(
      scaledInDouble(BlockScaling<Scalar>::fromHessian(H_s, Preconditioning::kBlockJacobi), H));
  // The unit spread (1e5 in the columns, 1e10 in H) is what the scalings take out.
  EXPECT_LT(kappa_jacobi, 1e-8 * kappa) << kappa << " " << kappa_jacobi;
  EXPECT_LT(kappa_block, 1e-8 * kappa) << kappa << " " << kappa_block;
  // The within-quantity mixing is what the 3×3 blocks take out beyond the point scaling.
  EXPECT_LT(kappa_block, kappa_jacobi) << kappa_jacobi << " " << kappa_block;
}

TYPED_TEST(PreconditionerTest, ScaledMatrixMapsBackToTheSameHessian) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(32);
  const MatX<Scalar> H = illScaledHessian(rng, 2).cast<Scalar>();
  const MatXd Hd = H.template cast<double>();
  for (Preconditioning kind : {Preconditioning::kJacobi, Preconditioning::kBlockJacobi}) {
    const BlockScaling<Scalar> P = BlockScaling<Scalar>::fromHessian(H, kind);
    const MatXd back = P.unscaled(P.scaled(H)).template cast<double>();
    // Componentwise relative to √(H_ii H_jj), the scale every entry of an SPD matrix is bounded
    // by: the two congruences round each entry a few times over 2·3 terms, and P, Q are
    // inverse up to the rounding of one 3×3 block.
    const Eigen::VectorXd d = Hd.diagonal().cwiseSqrt();
    const double err = ((back - Hd).array() / (d * d.transpose()).array()).abs().maxCoeff();
    EXPECT_LE(err, 200 * eps<Scalar>()) << static_cast<int>(kind);
    EXPECT_LE(relError(P.unscaledGradient(P.scaledGradient(H.col(0))), H.col(0)),
              200 * eps<Scalar>());
    const VecX<Scalar> x = H.col(1);
    EXPECT_LE(relError(P.toDelta(P.toScaled(x)), x), 200 * eps<Scalar>());
  }
}

TYPED_TEST(PreconditionerTest, PreconditionedSolveMatchesTheDoubleReference) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(33);
  const MatX<Scalar> H = illScaledHessian(rng, 3).cast<Scalar>();
  const MatXd x_true = test::randomGaussian(rng, static_cast<int>(H.rows()), 1);
  const VecX<Scalar> b = (H.template cast<double>() * x_true).col(0).template cast<Scalar>();
  const MatXd Hd = H.template cast<double>();
  const Eigen::VectorXd x_ref = -Hd.ldlt().solve(b.template cast<double>());
  for (Preconditioning kind : {Preconditioning::kJacobi, Preconditioning::kBlockJacobi}) {
    const BlockScaling<Scalar> P = BlockScaling<Scalar>::fromHessian(H, kind);
    const double kappa = conditionNumber(scaledInDouble(P, Hd));
    const DampedSolve<Scalar> s = solveDampedLdlt<Scalar>(H, b, Scalar(0), Scalar(0), kind);
    ASSERT_TRUE(s.status.ok()) << s.status.toString();
    // Errors measured in the scaled coordinates y = Q δ, where the backward-stable LDLT's bound
    // n · ε · κ(Ĥ) holds.
    const VecX<Scalar> y = P.toScaled(s.delta);
    const VecX<Scalar> y_ref = P.toScaled(x_ref.cast<Scalar>());
    EXPECT_LE(relError(y, y_ref), 10.0 * H.rows() * eps<Scalar>() * kappa) << kappa;
  }
}

// The marginalizer's preconditioned path: the pseudo-inverse Schur complement of Ĥ, mapped back
// by the kept part of P, is the double reference H_κκ − H_κμ H_μμ⁻¹ H_μκ.
TYPED_TEST(PreconditionerTest, PreconditionedSchurComplementMatchesTheDoubleReference) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(34);
  const MatX<Scalar> H = illScaledHessian(rng, 3).cast<Scalar>();
  const MatXd Hd = H.template cast<double>();
  const VecX<Scalar> b = H.col(2);
  const int m = 12, k = static_cast<int>(H.rows()) - m;
  const MatXd S_ref =
      Hd.bottomRightCorner(k, k) -
      Hd.bottomLeftCorner(k, m) * Hd.topLeftCorner(m, m).ldlt().solve(Hd.topRightCorner(m, k));
  const BlockScaling<Scalar> P =
      BlockScaling<Scalar>::fromHessian(H, Preconditioning::kBlockJacobi);
  const SchurMarginalization<Scalar> sc =
      schurMarginalize<Scalar>(P.scaled(H), P.scaledGradient(b), m);
  ASSERT_TRUE(sc.status.ok()) << sc.status.toString();
  EXPECT_EQ(sc.marg_rank, m);
  const BlockScaling<Scalar> P_kept = P.tail(m);
  const double kappa = conditionNumber(scaledInDouble(P, Hd));
  // Compared in the kept variables' scaled coordinates (Ĥ has a unit-scale diagonal there).
  const MatXd S_ref_scaled = scaledInDouble(P_kept, S_ref);
  EXPECT_LE(relError(sc.prior.H.template cast<double>(), S_ref_scaled),
            10.0 * H.rows() * eps<Scalar>() * kappa)
      << kappa;
}

TYPED_TEST(PreconditionerTest, SingularOrNonFiniteSystemIsAStatus) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(35);
  MatX<Scalar> H = illScaledHessian(rng, 1).cast<Scalar>();
  // A quantity without information: its 3×3 block and couplings are zero.
  H.middleRows(3, 3).setZero();
  H.middleCols(3, 3).setZero();
  const VecX<Scalar> b = VecX<Scalar>::Ones(H.rows());
  for (Preconditioning kind : {Preconditioning::kJacobi, Preconditioning::kBlockJacobi}) {
    const BlockScaling<Scalar> P = BlockScaling<Scalar>::fromHessian(H, kind);
    EXPECT_TRUE(P.scaled(H).allFinite());
    const DampedSolve<Scalar> s = solveDampedLdlt<Scalar>(H, b, Scalar(0), Scalar(0), kind);
    EXPECT_EQ(s.status.code(), Status::Code::kSolveFailed) << s.status.toString();
    // The LM damping floor makes the same system solvable.
    EXPECT_TRUE(solveDampedLdlt<Scalar>(H, b, Scalar(0), Scalar(1), kind).status.ok());
    MatX<Scalar> H_nan = H;
    H_nan(0, 0) = std::numeric_limits<Scalar>::quiet_NaN();
    EXPECT_TRUE(BlockScaling<Scalar>::fromHessian(H_nan, kind).scaledGradient(b).allFinite());
    EXPECT_EQ(solveDampedLdlt<Scalar>(H_nan, b, Scalar(0), Scalar(1), kind).status.code(),
              Status::Code::kNotFinite);
  }
}

TEST(Preconditioner, JacobiScalesArePowersOfTwo) {
  MatXd H = MatXd::Zero(3, 3);
  H.diagonal() << 1e10, 3.0, 1e-8;
  const BlockScaling<double> P = BlockScaling<double>::fromHessian(H, Preconditioning::kJacobi);
  const MatXd H_s = P.scaled(H);
  for (int i = 0; i < 3; ++i) {
    int exponent = 0;
    EXPECT_EQ(std::frexp(P.toDelta(Eigen::Vector3d::Unit(i))[i], &exponent), 0.5);
    EXPECT_GE(H_s(i, i), 0.5);
    EXPECT_LE(H_s(i, i), 2.0);
  }
}

}  // namespace
}  // namespace marglab
