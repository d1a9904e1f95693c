// marginalize() on linear-Gaussian problems (exact marginals), rank-deficient blankets, robust
// losses (Triggs correction) and bad calls. Ceres is double only: no float instantiation here.

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <string>

#include "core/ceres_marg/marginalize.h"
#include "test/ceres_marg/test_helpers.h"

namespace marglab::ceres_marg {
namespace {

using test::LinearFactor;
using test::LinearGraph;

constexpr double kRel = 1e-8;  // the tolerance for marginals

std::string methodName(const ::testing::TestParamInfo<Method>& info) {
  std::string name = toString(info.param);
  for (char& c : name) c = c == '-' ? '_' : c;
  return name;
}

struct Marginals {
  Eigen::VectorXd x;
  Eigen::MatrixXd cov;
};

Marginals denseMarginals(const LinearGraph& g) {
  Eigen::MatrixXd J;
  Eigen::VectorXd c;
  g.dense(&J, &c);
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(H);
  return {ldlt.solve(-J.transpose() * c),
          ldlt.solve(Eigen::MatrixXd::Identity(H.rows(), H.cols()))};
}

void solveLinear(ceres::Problem* problem) {
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.initial_trust_region_radius = 1e16;
  options.function_tolerance = 1e-20;
  options.gradient_tolerance = 1e-20;
  options.parameter_tolerance = 1e-20;
  options.max_num_iterations = 5;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, problem, &summary);
}

Eigen::MatrixXd ceresCovarianceBlock(ceres::Problem* problem, double* a, double* b, int na,
                                     int nb) {
  ceres::Covariance::Options options;
  options.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance covariance(options);
  std::vector<std::pair<const double*, const double*>> pairs = {{a, b}};
  EXPECT_TRUE(covariance.Compute(pairs, problem));
  test::RowMatrix block(na, nb);
  EXPECT_TRUE(covariance.GetCovarianceBlock(a, b, block.data()));
  return block;
}

class LinearGaussian : public ::testing::TestWithParam<Method> {};

// After marginalizing any subset, the solution and the covariance of the remaining blocks equal
// the marginals of the full problem (dense reference and ceres::Covariance of the full problem).
TEST_P(LinearGaussian, RemainingProblemHasTheFullProblemsMarginals) {
  const std::vector<std::vector<int>> subsets = {{1}, {2, 3}, {0, 4}, {1, 3, 5}, {5}};
  for (unsigned seed = 1; seed <= 3; ++seed) {
    for (const std::vector<int>& subset : subsets) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << ", subset of " << subset.size()
                                        << " starting at " << subset[0]);
      LinearGraph full_graph = LinearGraph::random(6, 4, seed);
      const Marginals ref = denseMarginals(full_graph);
      ceres::Problem full;
      full_graph.addTo(&full);

      LinearGraph g = LinearGraph::random(6, 4, seed);
      ceres::Problem problem;
      g.addTo(&problem);
      std::vector<double*> blocks;
      for (int b : subset) blocks.push_back(g.x[b].data());
      MarginalizationOptions options;
      options.method = GetParam();
      const MarginalizationSummary summary = marginalize(&problem, blocks, options);
      ASSERT_TRUE(summary.status.ok()) << summary.status.toString();
      EXPECT_LE(summary.prior_rank, summary.blanket_dim);
      solveLinear(&problem);

      const std::vector<int> o = g.offsets();
      std::vector<int> kept;
      for (int b = 0; b < 6; ++b) {
        if (std::find(subset.begin(), subset.end(), b) == subset.end()) kept.push_back(b);
      }
      for (int a : kept) {
        const Eigen::VectorXd x_a = Eigen::Map<const Eigen::VectorXd>(g.x[a].data(), g.sizes[a]);
        const Eigen::VectorXd x_ref = ref.x.segment(o[a], g.sizes[a]);
        EXPECT_LE((x_a - x_ref).norm(), kRel * std::max(1.0, ref.x.norm())) << "block " << a;
        for (int b : kept) {
          const Eigen::MatrixXd cov =
              ceresCovarianceBlock(&problem, g.x[a].data(), g.x[b].data(), g.sizes[a], g.sizes[b]);
          const Eigen::MatrixXd cov_full = ceresCovarianceBlock(
              &full, full_graph.x[a].data(), full_graph.x[b].data(), g.sizes[a], g.sizes[b]);
          const Eigen::MatrixXd cov_ref = ref.cov.block(o[a], o[b], g.sizes[a], g.sizes[b]);
          const double scale = ref.cov.norm();
          EXPECT_LE((cov - cov_ref).norm(), kRel * scale) << "blocks " << a << "," << b;
          EXPECT_LE((cov - cov_full).norm(), kRel * scale) << "blocks " << a << "," << b;
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Methods, LinearGaussian,
                         ::testing::Values(Method::kQr, Method::kSchur, Method::kSparseSchur),
                         methodName);

struct PriorInfo {
  Eigen::MatrixXd Lambda;  // R̃ᵀR̃
  Eigen::VectorXd g;       // R̃ᵀr̃
  MarginalizationSummary summary;
};

PriorInfo priorInfo(const MarginalizationSummary& s) {
  PriorInfo info;
  info.summary = s;
  if (s.prior_cost != nullptr) {
    const Eigen::MatrixXd& R = s.prior_cost->sqrtInformation();
    info.Lambda = R.transpose() * R;
    info.g = R.transpose() * s.prior_cost->residualOffset();
  }
  return info;
}

TEST(QrAndSchur, GiveTheSamePrior) {
  for (unsigned seed = 1; seed <= 4; ++seed) {
    std::vector<PriorInfo> infos;
    for (Method m : {Method::kQr, Method::kSchur, Method::kSparseSchur}) {
      LinearGraph g = LinearGraph::random(7, 5, seed);
      ceres::Problem problem;
      g.addTo(&problem);
      MarginalizationOptions options;
      options.method = m;
      infos.push_back(priorInfo(marginalize(&problem, {g.x[2].data(), g.x[3].data()}, options)));
      ASSERT_TRUE(infos.back().summary.status.ok());
    }
    for (std::size_t k = 1; k < infos.size(); ++k) {
      EXPECT_EQ(infos[k].summary.prior_rank, infos[0].summary.prior_rank);
      EXPECT_LE((infos[k].Lambda - infos[0].Lambda).norm(), 1e-10 * infos[0].Lambda.norm());
      EXPECT_LE((infos[k].g - infos[0].g).norm(), 1e-10 * std::max(1.0, infos[0].g.norm()));
    }
  }
}

// Relative factors x_j − x_i − z only: translation is a gauge freedom of the blanket, the prior
// has rank blanket_dim − 3 and annihilates a common translation; all methods agree.
TEST(RankDeficientBlanket, GaugeFreedomHandledIdenticallyByAllMethods) {
  const auto build = [](std::vector<std::vector<double>>* x, ceres::Problem* problem) {
    std::mt19937 rng(7);
    std::normal_distribution<double> normal;
    x->assign(5, std::vector<double>(3));
    for (auto& block : *x) {
      for (double& v : block) v = normal(rng);
      problem->AddParameterBlock(block.data(), 3);
    }
    for (auto [i, j] :
         std::vector<std::pair<int, int>>{{0, 1}, {1, 2}, {2, 3}, {3, 4}, {0, 2}, {2, 4}}) {
      Eigen::VectorXd z(3);
      z << normal(rng), normal(rng), normal(rng);
      problem->AddResidualBlock(
          new LinearFactor({-Eigen::MatrixXd::Identity(3, 3), Eigen::MatrixXd::Identity(3, 3)}, z),
          nullptr, (*x)[i].data(), (*x)[j].data());
    }
  };
  std::vector<PriorInfo> infos;
  for (Method m : {Method::kQr, Method::kSchur, Method::kSparseSchur}) {
    std::vector<std::vector<double>> x;
    ceres::Problem problem;
    build(&x, &problem);
    MarginalizationOptions options;
    options.method = m;
    infos.push_back(priorInfo(marginalize(&problem, {x[2].data()}, options)));
    const MarginalizationSummary& s = infos.back().summary;
    ASSERT_TRUE(s.status.ok()) << s.status.toString();
    EXPECT_EQ(s.blanket_dim, 12);
    EXPECT_EQ(s.prior_rank, 9) << toString(m);
    const Eigen::MatrixXd& R = s.prior_cost->sqrtInformation();
    for (int axis = 0; axis < 3; ++axis) {
      Eigen::VectorXd t = Eigen::VectorXd::Zero(12);
      for (int b = 0; b < 4; ++b) t[3 * b + axis] = 1.0;
      EXPECT_LE((R * t).norm(), 1e-12 * R.norm()) << toString(m) << " axis " << axis;
    }
  }
  for (std::size_t k = 1; k < infos.size(); ++k) {
    EXPECT_LE((infos[k].Lambda - infos[0].Lambda).norm(), 1e-10 * infos[0].Lambda.norm());
    EXPECT_LE((infos[k].g - infos[0].g).norm(), 1e-10 * std::max(1.0, infos[0].g.norm()));
  }
}

// ρ(s) = s + c s²: ρ'' > 0, so Ceres' Triggs correction has α ≠ 0 (Huber and Cauchy clamp α = 0
// in the region where ρ'' ≤ 0 and only scale by √ρ').
class QuadraticLoss final : public ceres::LossFunction {
 public:
  explicit QuadraticLoss(double c) : c_(c) {}
  void Evaluate(double s, double rho[3]) const override {
    rho[0] = s + c_ * s * s;
    rho[1] = 1 + 2 * c_ * s;
    rho[2] = 2 * c_;
  }

 private:
  double c_;
};

// Triggs correction as Ceres applies it (Triggs et al. 1999; primer §5.3).
void triggs(const ceres::LossFunction& loss, Eigen::VectorXd* f, Eigen::MatrixXd* J) {
  const double s = f->squaredNorm();
  double rho[3];
  loss.Evaluate(s, rho);
  const double sqrt_rho1 = std::sqrt(rho[1]);
  if (s == 0.0 || rho[2] <= 0.0) {
    *f *= sqrt_rho1;
    *J *= sqrt_rho1;
    return;
  }
  const double alpha = 1.0 - std::sqrt(1.0 + 2.0 * s * rho[2] / rho[1]);
  *J = sqrt_rho1 * (*J - (alpha / s) * (*f) * (f->transpose() * (*J)));
  *f *= sqrt_rho1 / (1.0 - alpha);
}

class RobustLoss : public ::testing::TestWithParam<int> {};

TEST_P(RobustLoss, PriorIsTheSchurComplementOfTheTriggsCorrectedSystem) {
  const std::vector<std::shared_ptr<ceres::LossFunction>> losses = {
      std::make_shared<QuadraticLoss>(0.3), std::make_shared<ceres::HuberLoss>(0.5),
      std::make_shared<ceres::CauchyLoss>(0.5)};
  const ceres::LossFunction& loss = *losses[GetParam()];
  // x_m (2) with a robust factor to the blanket (x_b, 2) and a plain unary factor.
  Eigen::MatrixXd A_m(2, 2), A_b(2, 2);
  A_m << 1.0, 0.3, -0.2, 0.9;
  A_b << 0.5, -1.0, 0.7, 0.4;
  const Eigen::VectorXd z = Eigen::Vector2d(2.0, -1.5);  // large residual: outlier region
  const Eigen::VectorXd z_m = Eigen::Vector2d(0.1, 0.2);
  for (Method m : {Method::kQr, Method::kSchur, Method::kSparseSchur}) {
    std::vector<double> x_m = {0.3, -0.4}, x_b = {0.2, 0.6};
    ceres::Problem::Options problem_options;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    problem.AddResidualBlock(new LinearFactor({A_m, A_b}, z),
                             const_cast<ceres::LossFunction*>(&loss), x_m.data(), x_b.data());
    problem.AddResidualBlock(new LinearFactor({Eigen::MatrixXd::Identity(2, 2)}, z_m), nullptr,
                             x_m.data());
    problem.AddResidualBlock(new LinearFactor({Eigen::MatrixXd::Identity(2, 2)}, z_m), nullptr,
                             x_b.data());

    // Independent reference: correct the raw residual and Jacobian, stack, Schur-complement.
    Eigen::VectorXd f1 =
        A_m * Eigen::Vector2d(x_m[0], x_m[1]) + A_b * Eigen::Vector2d(x_b[0], x_b[1]) - z;
    Eigen::MatrixXd J1(2, 4);
    J1 << A_m, A_b;
    const Eigen::VectorXd f1_raw = f1;
    const Eigen::MatrixXd J1_raw = J1;
    triggs(loss, &f1, &J1);
    Eigen::MatrixXd J(4, 4);
    J << J1, Eigen::MatrixXd::Identity(2, 2), Eigen::MatrixXd::Zero(2, 2);
    Eigen::VectorXd f(4);
    f << f1, Eigen::Vector2d(x_m[0], x_m[1]) - z_m;
    const Eigen::MatrixXd H = J.transpose() * J;
    const Eigen::VectorXd b = J.transpose() * f;
    const Eigen::MatrixXd H_mm_inv = H.topLeftCorner(2, 2).inverse();
    const Eigen::MatrixXd Lambda_t =
        H.bottomRightCorner(2, 2) - H.bottomLeftCorner(2, 2) * H_mm_inv * H.topRightCorner(2, 2);
    const Eigen::VectorXd g_t = b.tail(2) - H.bottomLeftCorner(2, 2) * H_mm_inv * b.head(2);
    // Without the loss, for contrast.
    Eigen::MatrixXd J_plain = J;
    J_plain.topRows(2) = J1_raw;
    const Eigen::MatrixXd H_plain = J_plain.transpose() * J_plain;
    const Eigen::MatrixXd Lambda_plain =
        H_plain.bottomRightCorner(2, 2) - H_plain.bottomLeftCorner(2, 2) *
                                              H_plain.topLeftCorner(2, 2).inverse() *
                                              H_plain.topRightCorner(2, 2);

    MarginalizationOptions options;
    options.method = m;
    const PriorInfo info = priorInfo(marginalize(&problem, {x_m.data()}, options));
    ASSERT_TRUE(info.summary.status.ok()) << info.summary.status.toString();
    EXPECT_LE((info.Lambda - Lambda_t).norm(), 1e-12 * Lambda_t.norm()) << toString(m);
    EXPECT_LE((info.g - g_t).norm(), 1e-12 * std::max(1.0, g_t.norm())) << toString(m);
    EXPECT_GT((Lambda_t - Lambda_plain).norm(), 1e-3 * Lambda_plain.norm())
        << "the loss must change the prior";
  }
}

INSTANTIATE_TEST_SUITE_P(Losses, RobustLoss, ::testing::Values(0, 1, 2),
                         [](const ::testing::TestParamInfo<int>& info) {
                           return std::string(info.param == 0   ? "quadratic_rho2_positive"
                                              : info.param == 1 ? "huber_outlier"
                                                                : "cauchy");
                         });

// A first-estimate linearization point of a linear problem gives the same prior cost function of
// x_b (the linearization is exact), anchored elsewhere.
TEST(LinearizationPoint, LinearProblemPriorIndependentOfTheAnchor) {
  for (Method m : {Method::kQr, Method::kSchur, Method::kSparseSchur}) {
    LinearGraph g1 = LinearGraph::random(5, 3, 11), g2 = LinearGraph::random(5, 3, 11);
    ceres::Problem p1, p2;
    g1.addTo(&p1);
    g2.addTo(&p2);
    MarginalizationOptions plain, fej;
    plain.method = fej.method = m;
    const MarginalizationSummary s1 = marginalize(&p1, {g1.x[2].data()}, plain);
    ASSERT_TRUE(s1.status.ok());
    for (double* block : s1.blanket) {
      const std::ptrdiff_t index =
          std::find_if(g1.x.begin(), g1.x.end(), [&](const auto& v) { return v.data() == block; }) -
          g1.x.begin();
      std::vector<double> lin = g2.x[index];
      for (double& v : lin) v += 0.7;
      fej.linearization_points[g2.x[index].data()] = lin;
    }
    const std::vector<double> before = g2.x[1];
    const MarginalizationSummary s2 = marginalize(&p2, {g2.x[2].data()}, fej);
    ASSERT_TRUE(s2.status.ok()) << s2.status.toString();
    EXPECT_EQ(g2.x[1], before) << "block values are restored after the evaluation";
    double cost1 = 0, cost2 = 0;
    p1.Evaluate(ceres::Problem::EvaluateOptions(), &cost1, nullptr, nullptr, nullptr);
    p2.Evaluate(ceres::Problem::EvaluateOptions(), &cost2, nullptr, nullptr, nullptr);
    EXPECT_NEAR(cost1, cost2, 1e-10 * std::max(1.0, cost1)) << toString(m);
  }
}

// ---- Bad calls leave the problem unchanged --------------------------------------------------

struct Snapshot {
  int parameter_blocks, residual_blocks;
  double cost;
  std::vector<std::vector<double>> values;
};

Snapshot snapshot(ceres::Problem* problem, const LinearGraph& g) {
  Snapshot s{problem->NumParameterBlocks(), problem->NumResidualBlocks(), 0, g.x};
  problem->Evaluate(ceres::Problem::EvaluateOptions(), &s.cost, nullptr, nullptr, nullptr);
  return s;
}

void expectUnchanged(ceres::Problem* problem, const LinearGraph& g, const Snapshot& before) {
  const Snapshot after = snapshot(problem, g);
  EXPECT_EQ(after.parameter_blocks, before.parameter_blocks);
  EXPECT_EQ(after.residual_blocks, before.residual_blocks);
  EXPECT_EQ(after.cost, before.cost);
  EXPECT_EQ(after.values, before.values);
}

class NaNFactor final : public ceres::SizedCostFunction<1, 2> {
 public:
  bool Evaluate(double const* const*, double* r, double** J) const override {
    r[0] = std::numeric_limits<double>::quiet_NaN();
    if (J != nullptr && J[0] != nullptr) J[0][0] = J[0][1] = 1.0;
    return true;
  }
};

TEST(BadCalls, ConstantBlock) {
  LinearGraph g = LinearGraph::random(4, 2, 3);
  ceres::Problem problem;
  g.addTo(&problem);
  problem.SetParameterBlockConstant(g.x[1].data());
  const Snapshot before = snapshot(&problem, g);
  const MarginalizationSummary s = marginalize(&problem, {g.x[1].data()});
  EXPECT_FALSE(s.status.ok());
  EXPECT_EQ(s.status.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.status.message().find("constant"), std::string::npos) << s.status.message();
  expectUnchanged(&problem, g, before);
}

TEST(BadCalls, BlockNotInProblemOrListedTwice) {
  LinearGraph g = LinearGraph::random(4, 2, 3);
  ceres::Problem problem;
  g.addTo(&problem);
  const Snapshot before = snapshot(&problem, g);
  double stranger[2] = {0, 0};
  MarginalizationSummary s = marginalize(&problem, {g.x[0].data(), stranger});
  EXPECT_EQ(s.status.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.status.message().find("not a parameter block"), std::string::npos);
  s = marginalize(&problem, {g.x[0].data(), g.x[0].data()});
  EXPECT_NE(s.status.message().find("twice"), std::string::npos);
  s = marginalize(&problem, {});
  EXPECT_FALSE(s.status.ok());
  expectUnchanged(&problem, g, before);
}

TEST(BadCalls, BoundedBlock) {
  LinearGraph g = LinearGraph::random(4, 2, 3);
  ceres::Problem problem;
  g.addTo(&problem);
  problem.SetParameterUpperBound(g.x[2].data(), 1, 10.0);
  const Snapshot before = snapshot(&problem, g);
  const MarginalizationSummary s = marginalize(&problem, {g.x[2].data()});
  EXPECT_EQ(s.status.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.status.message().find("bound"), std::string::npos);
  expectUnchanged(&problem, g, before);
}

TEST(BadCalls, NonFiniteJacobianAfterMovingTheBlanketRestoresIt) {
  LinearGraph g = LinearGraph::random(4, 2, 3);
  ceres::Problem problem;
  g.addTo(&problem);
  problem.AddResidualBlock(new NaNFactor, nullptr, g.x[0].data());
  const Snapshot before = snapshot(&problem, g);
  MarginalizationOptions options;
  options.linearization_points[g.x[1].data()] = std::vector<double>(g.sizes[1], 5.0);
  const MarginalizationSummary s = marginalize(&problem, {g.x[0].data()}, options);
  EXPECT_EQ(s.status.code(), Status::Code::kNotFinite) << s.status.toString();
  const Snapshot after = snapshot(&problem, g);
  EXPECT_EQ(after.parameter_blocks, before.parameter_blocks);
  EXPECT_EQ(after.residual_blocks, before.residual_blocks);
  EXPECT_EQ(after.values, before.values);  // the cost is NaN before and after
}

TEST(BadCalls, LinearizationPointOfWrongSizeOrOutsideTheBlanket) {
  LinearGraph g = LinearGraph::random(5, 0, 3);  // a chain: blanket of 2 is {1, 3}
  ceres::Problem problem;
  g.addTo(&problem);
  const Snapshot before = snapshot(&problem, g);
  MarginalizationOptions options;
  options.linearization_points[g.x[1].data()] = {1.0};
  MarginalizationSummary s = marginalize(&problem, {g.x[2].data()}, options);
  EXPECT_EQ(s.status.code(), Status::Code::kInvalidArgument);
  options.linearization_points.clear();
  options.linearization_points[g.x[4].data()] = g.x[4];
  s = marginalize(&problem, {g.x[2].data()}, options);
  EXPECT_NE(s.status.message().find("not in the Markov blanket"), std::string::npos);
  expectUnchanged(&problem, g, before);
}

TEST(ConstantNeighbour, IsConditionedOn) {
  LinearGraph g = LinearGraph::random(4, 0, 5);  // chain 0-1-2-3, unary on 0
  ceres::Problem problem;
  g.addTo(&problem);
  problem.SetParameterBlockConstant(g.x[0].data());
  const MarginalizationSummary s = marginalize(&problem, {g.x[1].data()});
  ASSERT_TRUE(s.status.ok()) << s.status.toString();
  EXPECT_EQ(s.constant_blanket_blocks, 1);
  EXPECT_EQ(s.blanket_blocks, 1);
  EXPECT_EQ(s.blanket, std::vector<double*>{g.x[2].data()});
}

}  // namespace
}  // namespace marglab::ceres_marg
