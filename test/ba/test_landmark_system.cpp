// The BAL linearization with the estimator's landmark blocks (core/ba/landmark_system.h): the
// nullspace (QR) and Schur-complement eliminations give the same reduced camera system and the
// same step (rootba's equivalence test, on its shrink-1800 problem), and PCG (core/ba/pcg.h)
// against a dense solve.
#include <fmt/core.h>
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <random>

#include "core/ba/ba_solver.h"
#include "core/ba/landmark_system.h"
#include "core/common/source_dir.h"

namespace marglab {
namespace {

BalProblem shipped(const std::string& name) {
  return loadBalProblem(std::string(sourceDir()) + "/datasets/bal/" + name);
}

double relativeError(const VecX<double>& a, const VecX<double>& b) {
  return (a - b).norm() / b.norm();
}

VecX<double> stacked(const BaStep<double>& step) {
  VecX<double> v(9 * step.delta_cameras.size() + 3 * step.delta_points.size());
  Eigen::Index k = 0;
  for (const auto& c : step.delta_cameras) v.segment<9>(std::exchange(k, k + 9)) = c;
  for (const auto& p : step.delta_points) v.segment<3>(std::exchange(k, k + 3)) = p;
  return v;
}

// Each nullspace storage (implicit, explicit rows) against the Schur complement, on the same
// linearization damped with the same λ. The reduced systems differ by the rounding of algorithms
// that are equal in exact arithmetic: a few ε relative to the largest entry, amplified by the
// conditioning of the 3×3 landmark blocks (≈ 1 after the Jacobian scaling) — 1e-9 leaves the margin
// of ~10⁵ ε that rootba's equivalence test also uses.
void expectNullspaceEqualsSchur(BaElimination nullspace) {
  const BalProblem problem = shipped("ladybug-problem-49-7776-pre-shrink-1800.txt.bz2");
  const BalState<double> state = BalState<double>::fromProblem(problem);
  ThreadPool pool(1);
  const auto ns = makeBaLinearSystem<double>(problem, nullspace, pool);
  const auto sc = makeBaLinearSystem<double>(problem, BaElimination::kSchur, pool);
  ASSERT_TRUE(ns->linearize(state, RobustLoss{}).ok());
  ASSERT_TRUE(sc->linearize(state, RobustLoss{1.0}).ok());  // a different loss: relinearized below
  ASSERT_TRUE(sc->linearize(state, RobustLoss{}).ok());
  BaStep<double> step_ns, step_sc;
  const double lambda = 1e-4;
  ASSERT_TRUE(ns->solve(lambda, CgOptions{}, &step_ns).ok());
  ASSERT_TRUE(sc->solve(lambda, CgOptions{}, &step_sc).ok());
  MatX<double> S_ns, S_sc;
  VecX<double> g_ns, g_sc;
  ASSERT_TRUE(ns->denseReducedSystem(&S_ns, &g_ns).ok());
  ASSERT_TRUE(sc->denseReducedSystem(&S_sc, &g_sc).ok());
  const double S_error = (S_ns - S_sc).norm() / S_sc.norm();
  const double step_error = relativeError(stacked(step_ns), stacked(step_sc));
  testing::Test::RecordProperty("reduced_system_relative_error", fmt::format("{:.3e}", S_error));
  testing::Test::RecordProperty("step_relative_error", fmt::format("{:.3e}", step_error));
  EXPECT_LT(S_error, 1e-9);
  EXPECT_LT(relativeError(g_ns, g_sc), 1e-9);
  EXPECT_EQ(step_ns.cg.iterations, step_sc.cg.iterations);
  EXPECT_LT(step_error, 1e-9);
  EXPECT_NEAR(step_ns.model_change / step_sc.model_change, 1.0, 1e-9);
  EXPECT_LT(step_ns.model_change, 0);
}

TEST(LandmarkSystem, NullspaceAndSchurGiveTheSameReducedSystemAndStep) {
  expectNullspaceEqualsSchur(BaElimination::kNullspace);
}

TEST(LandmarkSystem, ExplicitNullspaceRowsAndSchurGiveTheSameReducedSystemAndStep) {
  expectNullspaceEqualsSchur(BaElimination::kNullspaceExplicit);
}

// CG on a random SPD system with condition number 10⁴, run to convergence, against LDLT: both
// errors are about κ ε ‖x‖, so 1e3 · κ ε bounds their difference.
TEST(Pcg, ConvergesToTheDenseSolve) {
  const int n = 60;
  std::mt19937 rng(3);
  std::normal_distribution<double> normal;
  MatX<double> Q = MatX<double>::NullaryExpr(n, n, [&] { return normal(rng); });
  Q = Eigen::HouseholderQR<MatX<double>>(Q).householderQ();
  VecX<double> eigenvalues = VecX<double>::LinSpaced(n, 0.0, 4.0);
  eigenvalues = eigenvalues.unaryExpr([](double e) { return std::pow(10.0, e); });
  const MatX<double> A = Q * eigenvalues.asDiagonal() * Q.transpose();
  const VecX<double> b = VecX<double>::NullaryExpr(n, [&] { return normal(rng); });
  CgOperators<double> ops;
  ops.apply_A = [&](const VecX<double>& x, VecX<double>* Ax) { *Ax = A * x; };
  ops.apply_M_inverse = [&](const VecX<double>& r, VecX<double>* z) {
    *z = r.cwiseQuotient(A.diagonal());
  };
  VecX<double> x;
  CgSummary summary;
  ASSERT_TRUE(preconditionedCg(ops, b, CgOptions{10 * n, 1e-14}, &x, &summary).ok());
  const VecX<double> x_dense = A.ldlt().solve(b);
  EXPECT_LT(relativeError(x, x_dense), 1e3 * 1e4 * std::numeric_limits<double>::epsilon())
      << summary.iterations << " iterations, " << summary.message;
  // The Ritz values lie inside the spectrum of M⁻¹A.
  const auto spectrum = Eigen::SelfAdjointEigenSolver<MatX<double>>(
                            A.diagonal().cwiseSqrt().cwiseInverse().asDiagonal() * A *
                            A.diagonal().cwiseSqrt().cwiseInverse().asDiagonal())
                            .eigenvalues();
  EXPECT_GE(summary.ritz_min, spectrum.minCoeff() * (1 - 1e-8));
  EXPECT_LE(summary.ritz_max, spectrum.maxCoeff() * (1 + 1e-8));
}

TEST(Pcg, NonPositiveCurvatureIsAStatus) {
  CgOperators<float> ops;
  ops.apply_A = [](const VecX<float>& x, VecX<float>* Ax) { *Ax = -x; };
  ops.apply_M_inverse = [](const VecX<float>& r, VecX<float>* z) { *z = r; };
  VecX<float> x;
  CgSummary summary;
  const Status status =
      preconditionedCg(ops, VecX<float>(VecX<float>::Ones(4)), CgOptions{}, &x, &summary);
  EXPECT_EQ(status.code(), Status::Code::kSolveFailed);
  EXPECT_NE(status.message().find("f32"), std::string::npos) << status.message();
}

// A short run of every solver: on the 3-camera problem the cost falls by orders of magnitude; on
// shrink-1800 (normalized as rootba does) the elimination solvers and the Ceres peers (same model,
// start and loss) reach the same cost after 5 iterations. Each stops when a step changes the cost
// by less than 1e-6 of it, so they can part by a few such steps: 1e-5 relative.
TEST(BundleAdjustment, EverySolverDecreasesTheCostAndTheyAgree) {
  const BalProblem tiny = shipped("dubrovnik-3-7-pre.txt");
  BalProblem shrink = shipped("ladybug-problem-49-7776-pre-shrink-1800.txt.bz2");
  normalizeBalProblem(&shrink, 100);
  double reference = 0;
  for (const std::string& name : baSolverNames()) {
    BaOptions options;
    options.solver = parseBaSolver(name);
    options.iterations = 10;
    const BaResult result = solveBundleAdjustment(tiny, options);
    // f32: the problem rounded to float moves the cost by ~ε_f relative per residual.
    EXPECT_NEAR(result.initial_cost / 2.7642199844e+03, 1.0, 1e-5) << name;
    EXPECT_LT(result.final_cost, 1e-3 * result.initial_cost) << name << " " << result.reason;
    EXPECT_EQ(result.status, "max_iterations") << name << " " << result.reason;
    EXPECT_EQ(result.iterations.size(), 11u) << name;
    options.iterations = 5;
    const BaResult shrunk = solveBundleAdjustment(shrink, options);
    if (reference == 0) reference = shrunk.final_cost;
    EXPECT_NEAR(shrunk.final_cost / reference, 1.0, 1e-5) << name;
  }
}

// A point at a camera's centre (P_z = 0): the residual is not finite. Every solver records the
// failure as its status and reason and returns; none crashes or throws.
TEST(BundleAdjustment, NumericalFailureIsARecordedStatus) {
  BalProblem problem = shipped("dubrovnik-3-7-pre.txt");
  const BalObservation& obs = problem.observations.front();
  const SnavelyCamera<double> camera = SnavelyCamera<double>::fromBal(problem.cameras[obs.camera]);
  problem.points[obs.point] = -camera.R_c_w.transpose() * camera.t_c_w;
  for (const std::string& name : baSolverNames()) {
    BaOptions options;
    options.solver = parseBaSolver(name);
    options.iterations = 3;
    const BaResult result = solveBundleAdjustment(problem, options);
    EXPECT_EQ(result.status, "failed") << name;
    EXPECT_FALSE(result.reason.empty()) << name;
  }
}

// A point seen once (2 rows for 3 unknowns) cannot be eliminated: it stays fixed, is counted, and
// the others are solved.
TEST(BundleAdjustment, PointsSeenOnceStayFixed) {
  BalProblem problem = shipped("dubrovnik-3-7-pre.txt");
  const int point = problem.observations.back().point;
  std::vector<BalObservation> kept;
  bool seen = false;
  for (const BalObservation& obs : problem.observations) {
    if (obs.point == point && std::exchange(seen, true)) continue;
    kept.push_back(obs);
  }
  problem.observations = kept;
  BaOptions options;
  options.iterations = 5;
  const BaResult result = solveBundleAdjustment(problem, options);
  EXPECT_EQ(result.num_fixed_points, 1);
  EXPECT_LT(result.final_cost, result.initial_cost);
}

// Threads: the eliminations linearize, multiply and back-substitute over the landmark blocks in
// parallel with reductions whose order does not depend on the thread count (per camera in landmark
// order; sc's reduced system in fixed chunks), so 1, 2 and 3 threads give the same run bit for bit:
// every trial's cost, λ, CG iterations and Ritz values. On shrink-1800 under rootba's protocol
// (normalized, perturbed, Huber), where steps are rejected and CG runs tens of iterations.
TEST(BundleAdjustment, ThreadCountDoesNotChangeTheNumbers) {
  BalProblem problem = shipped("ladybug-problem-49-7776-pre-shrink-1800.txt.bz2");
  normalizeBalProblem(&problem, 100);
  perturbBalProblem(&problem, 0.01, 38401);
  for (const std::string name : {"ns-f32", "ns-f64", "nsx-f32", "nsx-f64", "sc-f32", "sc-f64"}) {
    BaOptions options;
    options.solver = parseBaSolver(name);
    options.iterations = 8;
    options.huber_px = 1;
    const BaResult one = solveBundleAdjustment(problem, options);
    for (const int threads : {2, 3}) {
      options.threads = threads;
      const BaResult many = solveBundleAdjustment(problem, options);
      EXPECT_EQ(many.final_cost, one.final_cost) << name << " " << threads;
      ASSERT_EQ(many.iterations.size(), one.iterations.size()) << name << " " << threads;
      for (size_t i = 0; i < one.iterations.size(); ++i) {
        const BaIteration &a = one.iterations[i], &b = many.iterations[i];
        EXPECT_EQ(b.cost, a.cost) << name << " " << threads << " " << i;
        EXPECT_EQ(b.lambda, a.lambda) << name << " " << threads << " " << i;
        EXPECT_EQ(b.cg_iterations, a.cg_iterations) << name << " " << threads << " " << i;
        EXPECT_EQ(b.accepted, a.accepted) << name << " " << threads << " " << i;
        EXPECT_TRUE(b.ritz_max == a.ritz_max || (std::isnan(a.ritz_max) && std::isnan(b.ritz_max)))
            << name << " " << threads << " " << i;
      }
    }
  }
}

}  // namespace
}  // namespace marglab
