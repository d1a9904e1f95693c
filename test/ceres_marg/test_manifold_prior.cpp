// The prior on manifolds: quaternion Minus and its exact derivative against Ceres and central
// differences, and the prior's Jacobian away from the linearization point (rotation averaging,
// SE(3) products, a user manifold), which Ceres' MinusJacobian(x̌) gets wrong.

#include <ceres/ceres.h>
#include <ceres/product_manifold.h>
#include <ceres/rotation.h>
#include <ceres/sphere_manifold.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/ceres_marg/marginalize.h"
#include "test/ceres_marg/test_helpers.h"

namespace marglab::ceres_marg {
namespace {

using test::RowMatrix;
constexpr double kEps = std::numeric_limits<double>::epsilon();

Eigen::Vector4d randomQuaternion(std::mt19937* rng) {
  std::normal_distribution<double> normal;
  Eigen::Vector4d q(normal(*rng), normal(*rng), normal(*rng), normal(*rng));
  q.normalize();
  if (q[0] < 0) q = -q;  // w ≥ 0 for the ceres order, so small rotations are near identity
  return q;
}

TEST(QuaternionMinus, MatchesCeresAndItsMinusJacobianAtTheAnchor) {
  std::mt19937 rng(3);
  const ceres::QuaternionManifold ceres_q;
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Vector4d x = randomQuaternion(&rng);
    Eigen::Vector4d y = randomQuaternion(&rng);
    if (trial % 2 == 0) {  // near x, including the series branch
      const Eigen::Vector3d d = Eigen::Vector3d::Random() * std::pow(10.0, -(trial % 9));
      ceres_q.Plus(x.data(), d.data(), y.data());
    }
    Eigen::Vector3d mine, theirs;
    quaternionMinus<true>(y.data(), x.data(), mine.data());
    ceres_q.Minus(y.data(), x.data(), theirs.data());
    EXPECT_LE((mine - theirs).norm(), 4 * kEps * std::max(1.0, theirs.norm()));
  }
  std::string what;
  const auto diff = makeBlockDifference(&ceres_q, 4, &what);
  ASSERT_NE(diff, nullptr);
  const Eigen::Vector4d x = randomQuaternion(&rng);
  RowMatrix D(3, 4), D_ceres(3, 4);
  Eigen::Vector3d delta;
  ASSERT_TRUE(diff->evaluate(x.data(), x.data(), delta.data(), D.data()));
  ceres_q.MinusJacobian(x.data(), D_ceres.data());
  EXPECT_LE((D - D_ceres).norm(), 8 * kEps);
  EXPECT_LE(delta.norm(), 4 * kEps);
}

// Central differences of δ(y) = Minus(y, x̌) along the tangent at y: D_y · PlusJacobian(y).
template <typename Manifold>
void checkDifferenceJacobian(const Manifold& manifold, const std::vector<double>& y,
                             const std::vector<double>& x_lin) {
  std::string what;
  const auto diff = makeBlockDifference(&manifold, manifold.AmbientSize(), &what);
  ASSERT_NE(diff, nullptr) << what;
  const int n = manifold.AmbientSize(), t = manifold.TangentSize();
  RowMatrix D(t, n), P(n, t);
  Eigen::VectorXd delta(t);
  ASSERT_TRUE(diff->evaluate(y.data(), x_lin.data(), delta.data(), D.data()));
  manifold.PlusJacobian(y.data(), P.data());
  const Eigen::MatrixXd J = D * P;
  const double h = 1e-5;
  Eigen::MatrixXd J_num(t, t);
  for (int k = 0; k < t; ++k) {
    Eigen::VectorXd e = Eigen::VectorXd::Zero(t);
    e[k] = h;
    std::vector<double> yp(n), ym(n);
    manifold.Plus(y.data(), e.data(), yp.data());
    e[k] = -h;
    manifold.Plus(y.data(), e.data(), ym.data());
    Eigen::VectorXd dp(t), dm(t);
    manifold.Minus(yp.data(), x_lin.data(), dp.data());
    manifold.Minus(ym.data(), x_lin.data(), dm.data());
    J_num.col(k) = (dp - dm) / (2 * h);
  }
  // Central differences: truncation O(h²) and rounding O(ε/h) on O(1) quantities.
  const double tol = 10 * (h * h + kEps / h) * std::max(1.0, J.norm());
  EXPECT_LE((J - J_num).norm(), tol) << "J\n" << J << "\nnumerical\n" << J_num;
}

TEST(BlockDifference, ExactJacobianAwayFromTheAnchor) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::Vector4d x = randomQuaternion(&rng), y = randomQuaternion(&rng);
    const std::vector<double> xs(x.data(), x.data() + 4), ys(y.data(), y.data() + 4);
    checkDifferenceJacobian(ceres::QuaternionManifold(), ys, xs);
    const std::vector<double> xe = {xs[1], xs[2], xs[3], xs[0]}, ye = {ys[1], ys[2], ys[3], ys[0]};
    checkDifferenceJacobian(ceres::EigenQuaternionManifold(), ye, xe);
    std::vector<double> xp = xs, yp = ys;
    xp.insert(xp.end(), {1.0, -2.0, 0.5});
    yp.insert(yp.end(), {0.3, 0.4, -1.0});
    checkDifferenceJacobian(
        ceres::ProductManifold<ceres::QuaternionManifold, ceres::EuclideanManifold<3>>(), yp, xp);
    std::vector<double> xt = {1.0, -2.0, 0.5}, yt = {0.3, 0.4, -1.0};
    xt.insert(xt.end(), xe.begin(), xe.end());
    yt.insert(yt.end(), ye.begin(), ye.end());
    checkDifferenceJacobian(
        ceres::ProductManifold<ceres::EuclideanManifold<3>, ceres::EigenQuaternionManifold>(), yt,
        xt);
  }
}

// A user manifold: S¹ as a unit complex number, Plus rotates by δ, Minus = atan2(cross, dot).
struct CircleFunctor {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    using std::cos;
    using std::sin;
    x_plus_delta[0] = cos(delta[0]) * x[0] - sin(delta[0]) * x[1];
    x_plus_delta[1] = sin(delta[0]) * x[0] + cos(delta[0]) * x[1];
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    using std::atan2;
    y_minus_x[0] = atan2(x[0] * y[1] - x[1] * y[0], x[0] * y[0] + x[1] * y[1]);
    return true;
  }
};
using CircleManifold = MarginalizableAutoDiffManifold<CircleFunctor, 2, 1>;

TEST(BlockDifference, UserManifoldThroughMarginalizableAutoDiffManifold) {
  const std::vector<double> x = {std::cos(0.3), std::sin(0.3)}, y = {std::cos(1.4), std::sin(1.4)};
  checkDifferenceJacobian(CircleManifold(), y, x);
}

TEST(BlockDifference, UnsupportedManifoldIsNamed) {
  const ceres::SphereManifold<3> sphere;
  std::string what;
  EXPECT_EQ(makeBlockDifference(&sphere, 3, &what), nullptr);
  EXPECT_NE(what.find("DifferentiableMinus"), std::string::npos) << what;
}

// Relative rotation factor r = Minus(q_j, q_ij ⊗ q_i) in the ceres quaternion tangent (w first).
struct RelativeRotation {
  Eigen::Vector4d q_ij;
  template <typename T>
  bool operator()(const T* q_i, const T* q_j, T* r) const {
    const T q_ij_t[4] = {T(q_ij[0]), T(q_ij[1]), T(q_ij[2]), T(q_ij[3])};
    T pred[4];
    ceres::QuaternionProduct(q_ij_t, q_i, pred);
    // Minus(q_j, pred): vector part of q_j ⊗ pred*, scaled (small-angle form is enough here).
    const T conj[4] = {pred[0], -pred[1], -pred[2], -pred[3]};
    T d[4];
    ceres::QuaternionProduct(q_j, conj, d);
    for (int k = 0; k < 3; ++k) r[k] = T(2) * d[k + 1];
    return true;
  }
};

// Rotation averaging with quaternions: marginalize one rotation, move the blanket away from the
// linearization point, compare the prior's tangent Jacobian (Ceres applies PlusJacobian) with
// central differences — and show that MinusJacobian(x̌) would be wrong there.
TEST(ManifoldPrior, RotationAveragingJacobianAwayFromLinearizationPoint) {
  std::mt19937 rng(9);
  const int n = 5;
  std::vector<Eigen::Vector4d> q(n);
  for (auto& qi : q) qi = randomQuaternion(&rng);
  ceres::Problem problem;
  for (auto& qi : q) problem.AddParameterBlock(qi.data(), 4, new ceres::QuaternionManifold);
  for (auto [i, j] :
       std::vector<std::pair<int, int>>{{0, 1}, {1, 2}, {2, 3}, {3, 4}, {0, 2}, {2, 4}}) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<RelativeRotation, 3, 4, 4>(
                                 new RelativeRotation{randomQuaternion(&rng)}),
                             nullptr, q[i].data(), q[j].data());
  }
  const MarginalizationSummary s = marginalize(&problem, {q[2].data()});
  ASSERT_TRUE(s.status.ok()) << s.status.toString();
  ASSERT_EQ(s.blanket_blocks, 4);
  ASSERT_NE(s.prior_block, nullptr);

  // Move every blanket rotation by ~0.4 rad.
  const ceres::QuaternionManifold manifold;
  for (double* block : s.blanket) {
    const Eigen::Vector3d d = 0.4 * Eigen::Vector3d::Random();
    Eigen::Vector4d moved;
    manifold.Plus(block, d.data(), moved.data());
    std::copy(moved.data(), moved.data() + 4, block);
  }
  const int rows = s.prior_rows;
  std::vector<RowMatrix> J(4, RowMatrix(rows, 3));
  std::vector<double*> J_ptr;
  for (auto& Jk : J) J_ptr.push_back(Jk.data());
  Eigen::VectorXd r(rows);
  ASSERT_TRUE(problem.EvaluateResidualBlock(s.prior_block, false, nullptr, r.data(), J_ptr.data()));
  const double h = 1e-5;
  for (int k = 0; k < 4; ++k) {
    double* block = s.blanket[k];
    const Eigen::Vector4d saved = Eigen::Map<Eigen::Vector4d>(block);
    Eigen::MatrixXd J_num(rows, 3);
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d e = Eigen::Vector3d::Zero();
      Eigen::VectorXd rp(rows), rm(rows);
      e[c] = h;
      manifold.Plus(saved.data(), e.data(), block);
      problem.EvaluateResidualBlock(s.prior_block, false, nullptr, rp.data(), nullptr);
      e[c] = -h;
      manifold.Plus(saved.data(), e.data(), block);
      problem.EvaluateResidualBlock(s.prior_block, false, nullptr, rm.data(), nullptr);
      J_num.col(c) = (rp - rm) / (2 * h);
    }
    std::copy(saved.data(), saved.data() + 4, block);
    const double tol = 10 * (h * h + kEps / h) * std::max(1.0, J[k].norm() + r.norm());
    EXPECT_LE((J[k] - J_num).norm(), tol) << "block " << k;

    // The shortcut R̃_k · MinusJacobian(x̌_k) · PlusJacobian(x_k) is measurably wrong here.
    const auto& x_lin = s.prior_cost->linearizationPoint()[k];
    RowMatrix M(3, 4), P(4, 3);
    manifold.MinusJacobian(x_lin.data(), M.data());
    manifold.PlusJacobian(block, P.data());
    const Eigen::MatrixXd J_naive = s.prior_cost->sqrtInformation().middleCols(3 * k, 3) * M * P;
    EXPECT_GT((J_naive - J_num).norm(), 100 * tol) << "block " << k;
  }
}

TEST(ManifoldPrior, UnsupportedBlanketManifoldLeavesProblemUnchanged) {
  double a[3] = {1, 0, 0}, b[3] = {0, 1, 0};
  ceres::Problem problem;
  problem.AddParameterBlock(a, 3);
  problem.AddParameterBlock(b, 3, new ceres::SphereManifold<3>);
  problem.AddResidualBlock(
      new test::LinearFactor({Eigen::MatrixXd::Identity(3, 3), Eigen::MatrixXd::Identity(3, 3)},
                             Eigen::Vector3d(1, 2, 3)),
      nullptr, a, b);
  const MarginalizationSummary s = marginalize(&problem, {a});
  EXPECT_EQ(s.status.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.status.message().find("not supported"), std::string::npos) << s.status.message();
  EXPECT_EQ(problem.NumParameterBlocks(), 2);
  EXPECT_EQ(problem.NumResidualBlocks(), 1);
}

}  // namespace
}  // namespace marglab::ceres_marg
