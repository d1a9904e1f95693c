// dubrovnik-3-7's f32 / f64 gap (README, "Bundle adjustment on real problems"): 19 observations
// give 38 residuals for 3 × 9 + 7 × 3 = 48 unknowns, so the problem has exact fits (cost 0) and its
// minimum is 0. Under rootba's protocol (50 iterations) neither precision is there yet — every
// step is still accepted and the cost still falls — so the 50-iteration final costs compare two
// unconverged trajectories, not two optima. Run long enough, each precision ends at its own
// evaluation floor: a residual r = f d p − z of an observation z is computed with an error of a
// few ε‖z‖, so the cost of an exact fit evaluates to about ½ Σ (ε‖z‖)² — 1e-8 in float,
// 1e-25 in double on this problem — and LM stops there (λ above its maximum: no step decreases
// the evaluated cost).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/ba/ba_solver.h"
#include "core/common/scalar.h"
#include "core/common/source_dir.h"

namespace marglab {
namespace {

BalProblem dubrovnikUnderProtocol(std::uint64_t seed) {
  BalProblem problem =
      loadBalProblem(std::string(sourceDir()) + "/datasets/bal/dubrovnik-3-7-pre.txt");
  normalizeBalProblem(&problem, 100);
  perturbBalProblem(&problem, 0.01, seed);
  return problem;
}

// ½ Σ (ε ‖z‖)²: the cost an exact fit evaluates to when each residual carries an error ε‖z‖.
double evaluationFloor(const BalProblem& problem, double eps) {
  double floor = 0;
  for (const BalObservation& obs : problem.observations)
    floor += 0.5 * std::pow(eps * obs.z.norm(), 2);
  return floor;
}

TEST(BaDubrovnik3, ItsMinimumIsAnExactFit) {
  const BalProblem problem = dubrovnikUnderProtocol(38401);
  EXPECT_LT(2 * problem.numObservations(), 9 * problem.numCameras() + 3 * problem.numPoints());
}

template <typename To, typename From>
BalState<To> castState(const BalState<From>& state) {
  BalState<To> out;
  for (const auto& camera : state.cameras) out.cameras.push_back(camera.template cast<To>());
  for (const auto& point : state.points) out.points.push_back(point.template cast<To>());
  return out;
}

// After rootba's 50 iterations both precisions are still descending (over the last 10 iterations
// the cost falls by more than 1 %; a converged run stops once a step gains less than 1e-6), and
// the f32 / f64 gap is not the rounding of the cost's evaluation: evaluating the f64 end point in
// float moves its cost by less than a tenth of the gap, and the f32 end point evaluated in double
// keeps the gap. Over rootba's seed and the four of results/bal, with the explicit reduced rows
// (nsx, rootba's storage) the finding was made with; the implicit storage's f32 run ends nearer
// f64 on some seeds (seed 2: a gap of twice the float evaluation's rounding).
TEST(BaDubrovnik3, FiftyIterationsEndOnUnconvergedTrajectories) {
  for (const std::uint64_t seed : {38401, 1, 2, 3, 4}) {
    const BalProblem problem = dubrovnikUnderProtocol(seed);
    BaOptions options;
    options.iterations = 50;
    options.huber_px = 1;
    BalState<double> x64, x32;
    options.solver = BaSolver::kNsxF64;
    const BaResult r64 = solveBundleAdjustment(problem, options, &x64);
    options.solver = BaSolver::kNsxF32;
    const BaResult r32 = solveBundleAdjustment(problem, options, &x32);
    for (const BaResult* r : {&r64, &r32}) {
      EXPECT_EQ(r->status, "max_iterations") << seed;
      EXPECT_LT(r->iterations.back().cost, 0.99 * r->iterations[r->iterations.size() - 11].cost)
          << seed;
    }
    const RobustLoss loss{1.0};
    const double c64 = evaluateCost(problem.observations, x64, loss).cost;
    const double c64_in_float =
        evaluateCost(problem.observations, castState<float>(x64), loss).cost;
    const double c32_in_double = evaluateCost(problem.observations, x32, loss).cost;
    const double gap = std::abs(r32.final_cost - c64);
    EXPECT_LT(std::abs(c64_in_float - c64), gap / 10) << seed;
    EXPECT_NEAR(std::abs(c32_in_double - c64), gap, gap / 10) << seed;
  }
}

// Run to the end, each precision reaches the cost of an exact fit as its arithmetic evaluates it:
// within a factor 16 of ½ Σ (ε‖z‖)² (the error of f d p − z is a few ε‖z‖; squared, a factor of
// a few squared), f64 some 1e17 times below f32.
TEST(BaDubrovnik3, EachPrecisionEndsAtItsEvaluationFloor) {
  const BalProblem problem = dubrovnikUnderProtocol(38401);
  for (const auto& [solver, eps] :
       {std::pair{BaSolver::kNsF64, NumericTraits<double>::kEpsilon},
        std::pair{BaSolver::kNsF32, double(NumericTraits<float>::kEpsilon)}}) {
    BaOptions options;
    options.solver = solver;
    options.iterations = 500;
    options.huber_px = 1;
    const BaResult result = solveBundleAdjustment(problem, options);
    const double floor = evaluationFloor(problem, eps);
    testing::Test::RecordProperty(std::string(toString(solver)) + "_final_over_floor",
                                  std::to_string(result.final_cost / floor));
    EXPECT_EQ(result.status, "no_convergence") << toString(solver) << " " << result.reason;
    EXPECT_LT(result.final_cost, 16 * floor) << toString(solver);
    EXPECT_GT(result.final_cost, floor / 16) << toString(solver);
  }
}

}  // namespace
}  // namespace marglab
