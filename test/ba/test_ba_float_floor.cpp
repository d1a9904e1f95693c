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

// After rootba's 50 iterations both precisions are still descending: over the last 10 iterations
// the cost falls by more than 1 % (a converged run stops once a step gains less than 1e-6).
TEST(BaDubrovnik3, FiftyIterationsDoNotConverge) {
  const BalProblem problem = dubrovnikUnderProtocol(38401);
  for (const BaSolver solver : {BaSolver::kNsF64, BaSolver::kNsF32}) {
    BaOptions options;
    options.solver = solver;
    options.iterations = 50;
    options.huber_px = 1;
    const BaResult result = solveBundleAdjustment(problem, options);
    EXPECT_EQ(result.status, "max_iterations") << toString(solver);
    const BaIteration& last = result.iterations.back();
    const BaIteration& before = result.iterations[result.iterations.size() - 11];
    EXPECT_LT(last.cost, 0.99 * before.cost) << toString(solver);
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
