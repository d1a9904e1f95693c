// Rigid-motion deflation (core/sparsify/rigid_deflation.h) on synthetic sparsified priors
// Λ_s = J_uᵀJ_u + Λ_inv: unary factors J_u that see the rigid directions E and an invariant part
// Λ_inv (Λ_inv E = 0, the pose–landmark and relative-pose factors), against dense priors Λ_d built
// with a chosen relation to Λ_s on span E. After deflation Λ_s' = Λ_s + J_uᵀ(AᵀA − I)J_u must
// carry Λ_d's information along every rigid direction that had too much, keep Λ_s on the
// Λ_s-orthogonal complement of span E, never add information, and stay positive semi-definite.
//
// Tolerances. Everything is O(1)-conditioned double arithmetic on n ≤ 40 columns: 1e-9 relative
// (the bound) is ~10⁶ ε; a near-zero μ_j loses relative accuracy as ε / √μ_j (A q_j is
// formed as q_j − (1 − √μ_j) q_j), which the near-singular case bounds absolutely.

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/sparsify/rigid_deflation.h"
#include "linalg/linalg_test_util.h"

namespace marglab {
namespace {

using test::randomGaussian;

constexpr int kRigid = 6;
constexpr double kRel = 1e-9;

MatXd symmetricSqrt(const MatXd& S) {
  const Eigen::SelfAdjointEigenSolver<MatXd> eig(S);
  return eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal() *
         eig.eigenvectors().transpose();
}

// A sparsified prior over n columns: m unary rows, an invariant part of rank n − 6 − 2.
struct Problem {
  MatXd E;         // n × 6, unit columns
  MatXd J_u;       // m × n
  MatXd Lambda_s;  // J_uᵀJ_u + Λ_inv
  MatXd G_s() const { return E.transpose() * Lambda_s * E; }
  MatXd B() const { return J_u * E; }
};

Problem makeProblem(std::mt19937_64& rng, int n, int m) {
  Problem p;
  p.E = randomGaussian(rng, n, kRigid).colwise().normalized();
  p.J_u = randomGaussian(rng, m, n);
  const MatXd P_perp =
      MatXd::Identity(n, n) - p.E * (p.E.transpose() * p.E).inverse() * p.E.transpose();
  const MatXd H_inv = randomGaussian(rng, n - kRigid - 2, n) * P_perp;  // H_inv E = 0
  p.Lambda_s = p.J_u.transpose() * p.J_u + H_inv.transpose() * H_inv;
  return p;
}

// G_d = G_s^(1/2) M G_s^(1/2) with M = P diag(mu) Pᵀ: the ratios dense / sparse along the
// generalized eigen-directions are mu (P random orthogonal unless given).
MatXd denseGram(const MatXd& G_s, const VecXd& mu, const MatXd& P) {
  const MatXd R = symmetricSqrt(G_s);
  return R * P * mu.asDiagonal() * P.transpose() * R;
}

MatXd randomOrthogonal(std::mt19937_64& rng, int d) {
  return Eigen::HouseholderQR<MatXd>(randomGaussian(rng, d, d)).householderQ();
}

MatXd deflated(const Problem& p, const RigidDeflation& d) {
  return p.Lambda_s + p.J_u.transpose() *
                          (d.A.transpose() * d.A - MatXd::Identity(d.A.rows(), d.A.cols())) * p.J_u;
}

double info(const MatXd& Lambda, const VecXd& e) { return e.dot(Lambda * e); }

// A random direction orthogonal to span E in the Λ_s inner product (to its numerical range, with
// G_s's pseudo-inverse, when Λ_s has next to no information along part of span E).
VecXd lambdaOrthogonal(std::mt19937_64& rng, const Problem& p) {
  const VecXd r = randomGaussian(rng, static_cast<int>(p.E.rows()), 1);
  const Eigen::SelfAdjointEigenSolver<MatXd> eig(p.G_s());
  const VecXd s = eig.eigenvalues();
  const VecXd s_inv = (s.array() > 1e-12 * s.maxCoeff()).select(s.cwiseInverse(), 0.0);
  const MatXd G_s_pinv = eig.eigenvectors() * s_inv.asDiagonal() * eig.eigenvectors().transpose();
  return r - p.E * (G_s_pinv * (p.E.transpose() * (p.Lambda_s * r)));
}

void expectPsd(const MatXd& Lambda) {
  const double lambda_min = Eigen::SelfAdjointEigenSolver<MatXd>(Lambda).eigenvalues().minCoeff();
  EXPECT_GE(lambda_min, -kRel * Lambda.norm());
}

void expectComplementUnchanged(std::mt19937_64& rng, const Problem& p, const MatXd& Lambda_new) {
  for (int trial = 0; trial < 3; ++trial) {
    const VecXd y = lambdaOrthogonal(rng, p);
    EXPECT_NEAR(info(Lambda_new, y), info(p.Lambda_s, y), kRel * info(p.Lambda_s, y));
    EXPECT_LE((Lambda_new * y - p.Lambda_s * y).norm(), kRel * (p.Lambda_s * y).norm());
  }
}

TEST(RigidDeflation, MatchesTheDensePriorAlongEveryRigidDirectionWithExcess) {
  std::mt19937_64 rng(11);
  const Problem p = makeProblem(rng, 40, 24);
  VecXd mu(kRigid);
  mu << 0.37, 0.41, 0.45, 0.2, 0.6, 0.48;  // Λ_s 1.7–5× Λ_d, as measured on EuRoC
  const MatXd G_d = denseGram(p.G_s(), mu, randomOrthogonal(rng, kRigid));
  const RigidDeflation d = rigidDeflation(p.B(), G_d);
  ASSERT_TRUE(d.status.ok()) << d.status.toString();
  EXPECT_EQ(d.deflated(), kRigid);
  const MatXd Lambda_new = deflated(p, d);
  for (int k = 0; k < kRigid; ++k) {
    const VecXd e = p.E.col(k);
    EXPECT_GT(info(p.Lambda_s, e), G_d(k, k));  // an excess to remove along every axis
    EXPECT_NEAR(info(Lambda_new, e), G_d(k, k), kRel * G_d(k, k)) << "rigid direction " << k;
  }
  // Every combination of them as well: EᵀΛ_s'E = G_d.
  EXPECT_LE((p.E.transpose() * Lambda_new * p.E - G_d).norm(), kRel * G_d.norm());
  expectComplementUnchanged(rng, p, Lambda_new);
  expectPsd(Lambda_new);
  EXPECT_NEAR(d.logDetChange(), mu.array().log().sum(), kRel);
}

TEST(RigidDeflation, ChangesNothingWhereTheSparsifiedPriorIsNotMoreConfident) {
  std::mt19937_64 rng(12);
  const Problem p = makeProblem(rng, 30, 18);
  VecXd mu(kRigid);
  mu << 1.0, 1.3, 2.0, 1.01, 5.0, 1.6;  // G_s ⪯ G_d, equality along one direction
  const RigidDeflation d = rigidDeflation(p.B(), denseGram(p.G_s(), mu, randomOrthogonal(rng, 6)));
  ASSERT_TRUE(d.status.ok()) << d.status.toString();
  EXPECT_EQ(d.deflated(), 0);
  EXPECT_TRUE(d.A.isIdentity(0.0));
  EXPECT_EQ(d.logDetChange(), 0.0);
}

// One rigid direction (roll) with less information in Λ_s than in Λ_d, the others with more:
// roll keeps its information, the deflated generalized directions get Λ_d's, and no rigid
// direction ends above either prior.
TEST(RigidDeflation, KeepsARigidDirectionThatIsNotOverconfident) {
  std::mt19937_64 rng(13);
  const Problem p = makeProblem(rng, 36, 24);
  const MatXd G_s = p.G_s();
  // P's first column along G_s^(1/2) e_roll: then e_roll is a generalized eigen-direction.
  const VecXd e_roll = VecXd::Unit(kRigid, 3);
  MatXd seed = randomGaussian(rng, kRigid, kRigid);
  seed.col(0) = symmetricSqrt(G_s) * e_roll;
  const MatXd P = Eigen::HouseholderQR<MatXd>(seed).householderQ();
  VecXd mu(kRigid);
  mu << 1.7, 0.3, 0.5, 0.4, 0.6, 0.45;
  const MatXd G_d = denseGram(G_s, mu, P);
  const RigidDeflation d = rigidDeflation(p.B(), G_d);
  ASSERT_TRUE(d.status.ok()) << d.status.toString();
  EXPECT_EQ(d.deflated(), kRigid - 1);
  const MatXd Lambda_new = deflated(p, d);
  const VecXd roll = p.E * e_roll;
  EXPECT_NEAR(info(Lambda_new, roll), info(p.Lambda_s, roll), kRel * info(p.Lambda_s, roll));
  EXPECT_LT(info(p.Lambda_s, roll), G_d(3, 3));
  for (int k = 0; k < kRigid; ++k) {
    const VecXd e = p.E.col(k);
    const double bound = std::min(info(p.Lambda_s, e), G_d(k, k));
    EXPECT_LE(info(Lambda_new, e), bound * (1 + kRel)) << "rigid direction " << k;
  }
  // The deflated generalized directions f_j = J_u⁺ q_j carry Λ_d's μ_j, in Λ_s's units (1).
  const MatXd G_new = p.E.transpose() * Lambda_new * p.E;
  const Eigen::GeneralizedSelfAdjointEigenSolver<MatXd> ratios(G_new, G_s);
  const Eigen::GeneralizedSelfAdjointEigenSolver<MatXd> dense_ratios(G_d, G_s);
  VecXd expected = dense_ratios.eigenvalues().cwiseMin(1.0);
  std::sort(expected.data(), expected.data() + expected.size());
  EXPECT_LE((ratios.eigenvalues() - expected).norm(), kRel);
  expectComplementUnchanged(rng, p, Lambda_new);
  expectPsd(Lambda_new);
}

// Near-singular on both sides: the unary factors carry (almost) no information along one rigid
// combination, and the dense prior almost none along another (the gauge of a prior without a
// gauge prior). Nothing is removed where there is nothing, the rest is matched, Λ_s' stays PSD.
TEST(RigidDeflation, NearSingularPriorsStayFiniteAndPositiveSemiDefinite) {
  std::mt19937_64 rng(14);
  Problem p = makeProblem(rng, 36, 24);
  // J_u E v = 1e-9 J_u⁰ E v: Λ_s's information along E v is ~1e-18 of the rest.
  const VecXd v = randomGaussian(rng, kRigid, 1).normalized();
  const VecXd Ev = p.E * v;
  const MatXd J0 = p.J_u;
  p.J_u = J0 - (1 - 1e-9) * (J0 * Ev) * Ev.transpose() / Ev.squaredNorm();
  p.Lambda_s += p.J_u.transpose() * p.J_u - J0.transpose() * J0;
  const MatXd G_s = p.G_s();
  // Λ_d: 1e-12 of Λ_s along one generalized direction of the well-determined part, 0.3–0.6
  // along the others, and more than Λ_s along E v.
  MatXd G_d = denseGram(G_s, (VecXd(kRigid) << 1e-12, 0.3, 0.4, 0.5, 0.6, 0.45).finished(),
                        randomOrthogonal(rng, kRigid));
  G_d += 1e-6 * (v * v.transpose()) * G_s.norm();
  const RigidDeflation d = rigidDeflation(p.B(), G_d);
  ASSERT_TRUE(d.status.ok()) << d.status.toString();
  EXPECT_TRUE(d.A.allFinite());
  EXPECT_GE(d.deflated(), 1);
  EXPECT_LE(d.deflated(), kRigid - 1);  // not along E v, where there is nothing to remove
  const MatXd Lambda_new = deflated(p, d);
  expectPsd(Lambda_new);
  for (int k = 0; k < kRigid; ++k) {
    const VecXd e = p.E.col(k);
    EXPECT_LE(info(Lambda_new, e), info(p.Lambda_s, e) * (1 + kRel)) << "rigid direction " << k;
    EXPECT_LE(info(Lambda_new, e), G_d(k, k) + kRel * G_s.norm()) << "rigid direction " << k;
  }
  // Along E v Λ_s' keeps the ~nothing Λ_s had.
  EXPECT_LE(std::abs(info(Lambda_new, Ev) - info(p.Lambda_s, Ev)), kRel * G_s.norm());
  expectComplementUnchanged(rng, p, Lambda_new);
}

TEST(RigidDeflation, NonFiniteInputIsAStatus) {
  std::mt19937_64 rng(15);
  const Problem p = makeProblem(rng, 20, 12);
  MatXd G_d = p.G_s();
  G_d(2, 1) = std::nan("");
  const RigidDeflation d = rigidDeflation(p.B(), G_d);
  EXPECT_FALSE(d.status.ok());
  EXPECT_TRUE(d.A.isIdentity(0.0));
  EXPECT_FALSE(rigidDeflation(p.B(), MatXd::Identity(5, 5)).status.ok());
}

}  // namespace
}  // namespace marglab
