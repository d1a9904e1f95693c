// core/diagnostics/prior_analysis.h against matrices with a constructed spectrum.

#include "core/diagnostics/prior_analysis.h"

#include <gtest/gtest.h>

#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace marglab {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

MatXd randomMatrix(int rows, int cols, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  MatXd M(rows, cols);
  for (int j = 0; j < cols; ++j) {
    for (int i = 0; i < rows; ++i) M(i, j) = normal(rng);
  }
  return M;
}

MatXd randomOrthogonal(int n, std::uint64_t seed) {
  const Eigen::HouseholderQR<MatXd> qr(randomMatrix(n, n, seed));
  return qr.householderQ() * MatXd::Identity(n, n);
}

// H = Q diag(λ) Qᵀ: the eigenvalues are λ up to the rounding of forming H, which is bounded by
// n ε max|λ| per entry (each entry sums n products); the eigensolver adds O(ε ‖H‖).
TEST(PriorAnalysis, RecoversAConstructedSpectrumWithNegativeAndZeroEigenvalues) {
  std::vector<double> lambda = {-3.0, -1e-2, 0.0, 0.0, 0.0, 1e-3, 2.0, 5.0, 40.0, 1e4};
  const int n = static_cast<int>(lambda.size());
  const MatXd Q = randomOrthogonal(n, 11);
  const Eigen::Map<const VecXd> l(lambda.data(), n);
  const MatXd H = Q * l.asDiagonal() * Q.transpose();

  const PriorSpectrum s = analyzePrior(H);
  ASSERT_TRUE(s.valid);
  ASSERT_EQ(s.eigenvalues.size(), n);
  const double max_abs = 1e4;
  const double tol = 4.0 * n * kEps * max_abs;
  std::sort(lambda.begin(), lambda.end());
  for (int i = 0; i < n; ++i)
    EXPECT_NEAR(s.eigenvalues(i), lambda[static_cast<std::size_t>(i)], tol);
  for (int i = 1; i < n; ++i) EXPECT_LE(s.eigenvalues(i - 1), s.eigenvalues(i));
  EXPECT_NEAR(s.sigma_min, -3.0, tol);
  EXPECT_NEAR(s.sigma_max, 1e4, tol);
  EXPECT_NEAR(s.tolerance, n * kEps * max_abs, 1e-6 * n * kEps * max_abs);
  EXPECT_EQ(s.n_negative, 2);
  EXPECT_EQ(s.rank, n - 3);
}

// On a diagonal matrix the eigenvalues are exact, so the threshold is tested precisely:
// τ = n ε max|λ| = 4 ε · 2.
TEST(PriorAnalysis, ThresholdSeparatesRoundingFromIndefiniteness) {
  const double tau = 4 * kEps * 2.0;
  VecXd d(4);
  d << 2.0, -0.5 * tau, 0.5 * tau, -2.0 * tau;
  const PriorSpectrum s = analyzePrior(d.asDiagonal().toDenseMatrix());
  ASSERT_TRUE(s.valid);
  EXPECT_DOUBLE_EQ(s.tolerance, tau);
  EXPECT_EQ(s.n_negative, 1);  // only −2τ
  EXPECT_EQ(s.rank, 2);        // 2 and −2τ
  EXPECT_DOUBLE_EQ(s.sigma_min, -2.0 * tau);
  EXPECT_DOUBLE_EQ(s.sigma_max, 2.0);
}

TEST(PriorAnalysis, UsesTheSymmetricPart) {
  MatXd H(2, 2);
  H << 2.0, 1.0, 3.0, 2.0;  // symmetric part [[2, 2], [2, 2]]: eigenvalues 0 and 4
  const PriorSpectrum s = analyzePrior(H);
  EXPECT_NEAR(s.sigma_min, 0.0, 4 * 2 * kEps * 4.0);
  EXPECT_NEAR(s.sigma_max, 4.0, 4 * 2 * kEps * 4.0);
  EXPECT_EQ(s.rank, 1);
}

TEST(PriorAnalysis, EmptyOrNonFiniteIsInvalidWithNaNs) {
  const PriorSpectrum empty = analyzePrior(MatXd(0, 0));
  EXPECT_FALSE(empty.valid);
  EXPECT_EQ(empty.eigenvalues.size(), 0);
  EXPECT_TRUE(std::isnan(empty.sigma_min));

  MatXd H = MatXd::Identity(3, 3);
  H(1, 2) = std::numeric_limits<double>::quiet_NaN();
  const PriorSpectrum bad = analyzePrior(H);
  EXPECT_FALSE(bad.valid);
  ASSERT_EQ(bad.eigenvalues.size(), 3);
  EXPECT_TRUE(bad.eigenvalues.array().isNaN().all());
  EXPECT_TRUE(std::isnan(bad.sigma_max));
  EXPECT_EQ(bad.rank, 0);
  EXPECT_EQ(bad.n_negative, 0);
}

TEST(PriorAnalysis, SqrtHessianAndGradientMatchTheProducts) {
  const MatXd J = randomMatrix(9, 6, 3);
  const VecXd r = randomMatrix(9, 1, 4);
  const MatXd H = hessianFromSqrt(J);
  const MatXd H_ref = J.transpose() * J;
  EXPECT_LE((H - H_ref).norm(), 9 * kEps * H_ref.norm());
  EXPECT_EQ((H - H.transpose()).norm(), 0.0);
  EXPECT_LE((gradientFromSqrt(J, r) - J.transpose() * r).norm(), 9 * kEps * J.norm() * r.norm());
}

// The paper's observation (§5.2, Fig. 1) in miniature: a rank-deficient square-root prior stored
// in f32 stays positive semi-definite when H_m = J_mᵀJ_m is formed in double, while the same
// Hessian formed in f32 has rounding errors of O(ε_f32 ‖H‖) on its zero eigenvalues, far beyond
// the double threshold τ, which show up as negative eigenvalues.
TEST(PriorAnalysis, Float32SquaredPriorIsIndefiniteWhileSqrtPriorIsNot) {
  const int n = 18, nullity = 6, rows = n - nullity;
  const MatXd J = randomMatrix(rows, n, 5) * 1e2;  // rank n − 6: a 6-dof nullspace
  const Eigen::MatrixXf J_f = J.cast<float>();
  const PriorSpectrum sqrt_prior = analyzePrior(hessianFromSqrt(J_f.cast<double>()));
  EXPECT_EQ(sqrt_prior.n_negative, 0);
  EXPECT_EQ(sqrt_prior.rank, rows);
  const Eigen::MatrixXf H_f = J_f.transpose() * J_f;
  const PriorSpectrum squared_prior = analyzePrior(H_f.cast<double>());
  EXPECT_GT(squared_prior.n_negative, 0);
  EXPECT_GT(squared_prior.rank, rows);
}

}  // namespace
}  // namespace marglab
