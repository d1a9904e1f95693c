// The damped LDLT step of the reduced camera system (core/linalg/rcs_solve.h) on a symmetric
// indefinite system — what an f32 Hessian prior turned indefinite gives the LM step — against an
// independent double computation (the eigendecomposition's inverse): by default such a system is
// a failed solve; with solve_indefinite (lm.indefinite_system = "solve", Basalt's optimize()) the
// pivoted LDLT's solution is returned and solves the damped system within n · ε · κ; a non-finite
// system stays a failure in both modes.

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <limits>

#include "core/linalg/rcs_solve.h"
#include "linalg/linalg_test_util.h"

namespace marglab {
namespace {

using test::eps;
using test::relError;

template <typename Scalar>
class RcsSolveTest : public ::testing::Test {};
TYPED_TEST_SUITE(RcsSolveTest, test::Scalars, test::ScalarName);

// H = Q diag(σ) Qᵀ with eigenvalues of both signs, |σ| in [1, 10] (κ = 10), Q random orthogonal.
MatXd indefiniteHessian(std::mt19937_64& rng, int n) {
  const MatXd Q = Eigen::HouseholderQR<MatXd>(test::randomGaussian(rng, n, n)).householderQ();
  Eigen::VectorXd sigma = Eigen::VectorXd::LinSpaced(n, 1.0, 10.0);
  for (int i = 0; i < n; i += 3) sigma[i] = -sigma[i];
  return Q * sigma.asDiagonal() * Q.transpose();
}

// −(H + D)⁻¹ b in double through the eigendecomposition, with the LM damping D of rcs_solve.h.
VecXd referenceStep(MatXd H, const VecXd& b, double lambda, double lambda_min) {
  for (Eigen::Index i = 0; i < H.rows(); ++i) H(i, i) += lmDamping(H(i, i), lambda, lambda_min);
  const Eigen::SelfAdjointEigenSolver<MatXd> eig(H);
  const VecXd inv = eig.eigenvalues().cwiseInverse();
  return -(eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose() * b);
}

double conditionNumber(const MatXd& H) {
  const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<MatXd>(H).eigenvalues().cwiseAbs();
  return ev.maxCoeff() / ev.minCoeff();
}

TYPED_TEST(RcsSolveTest, IndefiniteSystemFailsByDefaultAndIsSolvedOnRequest) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(41);
  const int n = 24;
  const MatXd Hd = indefiniteHessian(rng, n);
  const VecXd bd = test::randomGaussian(rng, n, 1);
  const MatX<Scalar> H = Hd.cast<Scalar>();
  const VecX<Scalar> b = bd.cast<Scalar>();
  // Undamped (λ = λ_min = 0) and damped: a small λ keeps the system indefinite.
  for (const double lambda : {0.0, 1e-3}) {
    const Scalar l = static_cast<Scalar>(lambda);
    const DampedSolve<Scalar> fail = solveDampedLdlt<Scalar>(H, b, l, Scalar(0));
    EXPECT_EQ(fail.status.code(), Status::Code::kSolveFailed) << fail.status.toString();
    const DampedSolve<Scalar> solved =
        solveDampedLdlt<Scalar>(H, b, l, Scalar(0), Preconditioning::kNone, true);
    ASSERT_TRUE(solved.status.ok()) << solved.status.toString();
    MatXd damped = H.template cast<double>();
    for (int i = 0; i < n; ++i) damped(i, i) += lmDamping(damped(i, i), lambda, 0.0);
    const double kappa = conditionNumber(damped);
    EXPECT_LE(relError(solved.delta, referenceStep(H.template cast<double>(), bd, lambda, 0.0)),
              10.0 * n * eps<Scalar>() * kappa)
        << "lambda " << lambda << ", kappa " << kappa;
  }
}

TYPED_TEST(RcsSolveTest, PositiveDefiniteSystemGivesTheSameStepInBothModes) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(42);
  const MatXd J = test::randomGaussian(rng, 40, 12);
  const MatX<Scalar> H = (J.transpose() * J).cast<Scalar>();
  const VecX<Scalar> b = test::randomGaussian(rng, 12, 1).cast<Scalar>();
  const DampedSolve<Scalar> a = solveDampedLdlt<Scalar>(H, b, Scalar(1e-3), Scalar(1e-6));
  const DampedSolve<Scalar> c =
      solveDampedLdlt<Scalar>(H, b, Scalar(1e-3), Scalar(1e-6), Preconditioning::kNone, true);
  ASSERT_TRUE(a.status.ok() && c.status.ok());
  EXPECT_EQ(a.delta, c.delta);  // the same factorization: bit-identical
}

TYPED_TEST(RcsSolveTest, NonFiniteSystemFailsInBothModes) {
  using Scalar = TypeParam;
  std::mt19937_64 rng(43);
  MatX<Scalar> H = indefiniteHessian(rng, 6).cast<Scalar>();
  H(2, 2) = std::numeric_limits<Scalar>::quiet_NaN();
  const VecX<Scalar> b = VecX<Scalar>::Ones(6);
  for (const bool indefinite : {false, true}) {
    EXPECT_EQ(
        solveDampedLdlt<Scalar>(H, b, Scalar(0), Scalar(0), Preconditioning::kNone, indefinite)
            .status.code(),
        Status::Code::kNotFinite);
  }
}

}  // namespace
}  // namespace marglab
