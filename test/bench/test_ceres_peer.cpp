// The Ceres peer (core/bench/ceres_window.h) against marglab's f64 estimator on every shipped
// captured window: the same energy term by term, and — run to convergence from the same start —
// the same solution.
//
// Why the comparison releases the first estimates: with first-estimate Jacobians (FEJ) the
// Jacobians of linearized frames are not the derivatives of the residuals at the current state,
// so the LM "gradient" Σ Jᵀρ'r is not the gradient of the cost; LM then stalls wherever the model's
// predicted decrease stops being realized, a point that depends on the path (Ceres' Triggs-
// corrected robust Jacobian and its damping rule differ from the estimator's IRLS rows and
// max(λH_ii, λ_min)). Measured on the shipped windows, FEJ endpoints differ by up to ~2e-5
// (relative) with costs within ~2e-8; with Jacobians at the current state (the prior keeps its
// constant J_m in both) the endpoints agree to ~1e-8. So the 1e-6 check runs without FEJ, and with
// FEJ the costs of both endpoints are checked against each other (both stall at the same cost
// level) — see marglab bench for the FEJ state differences.

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/bench/ceres_window.h"
#include "core/bench/perf_suite.h"
#include "core/bench/window_replay.h"

namespace marglab {
namespace {

// Largest relative difference between two sets of states: translation, rotation angle (relative
// to 1 rad), speed-bias and landmark blocks, each relative to max(‖block‖, 1).
double maxRelativeDifference(const WindowSnapshot::Step& a, const WindowSnapshot::Step& b,
                             std::string* where) {
  double worst = 0;
  auto note = [&](double d, const std::string& what) {
    if (!(d <= worst)) {
      worst = d;
      *where = what;
    }
  };
  EXPECT_EQ(a.frames.size(), b.frames.size());
  for (size_t i = 0; i < a.frames.size() && i < b.frames.size(); ++i) {
    const auto& fa = a.frames[i];
    const auto& fb = b.frames[i];
    EXPECT_EQ(fa.id, fb.id);
    const Vec<double, 6> d = boxMinus<double>(fa.T_w_i, fb.T_w_i);
    note(d.head<3>().norm() / std::max(1.0, fa.T_w_i.translation().norm()),
         "translation of frame " + std::to_string(fa.id));
    note(d.tail<3>().norm(), "rotation of frame " + std::to_string(fa.id));
    EXPECT_EQ(fa.has_speed_bias, fb.has_speed_bias);
    if (fa.has_speed_bias && fb.has_speed_bias) {
      note((fa.speed_bias - fb.speed_bias).norm() / std::max(1.0, fa.speed_bias.norm()),
           "speed-bias of frame " + std::to_string(fa.id));
    }
  }
  std::map<int64_t, Eigen::Vector3d> lb;
  for (const auto& l : b.landmarks) lb[l.id] = l.param;
  size_t matched = 0;
  for (const auto& l : a.landmarks) {
    if (lb.count(l.id) == 0) continue;
    ++matched;
    note((l.param - lb[l.id]).norm() / std::max(1.0, l.param.norm()),
         "landmark " + std::to_string(l.id));
  }
  EXPECT_GT(matched, a.landmarks.size() / 2);
  return worst;
}

// The states of the window itself, as a step (the starting point).
WindowSnapshot::Step startOf(const WindowSnapshot& w) {
  WindowSnapshot::Step s;
  s.frames = w.frames;
  s.landmarks = w.landmarks;
  return s;
}

struct Converged {
  ReplayResult marglab;
  // The bench's exact solvers: DENSE_SCHUR, SPARSE_SCHUR, DENSE_QR. ITERATIVE_SCHUR (also in the
  // bench) solves each step inexactly (truncated CG) and ends measurably off marglab's solution and
  // not at the same cost from run to run, so it is not held to the exact comparison here.
  std::vector<std::pair<std::string, CeresWindowResult>> ceres;
};

Converged solveToConvergence(const WindowSnapshot& w) {
  EstimatorSettings tight = w.config;
  tight.lm_max_iterations = 400;
  tight.stop_relative_cost = 1e-16;
  tight.stop_max_step = 1e-12;
  Converged c;
  c.marglab = replayWindow(w, Variant::parse("ns-qr-sqrt-f64"), tight);
  CeresWindowOptions options;
  options.max_iterations = 400;
  options.function_tolerance = 1e-16;
  options.parameter_tolerance = 1e-14;
  options.gradient_tolerance = 1e-16;
  for (auto solver : {ceres::DENSE_SCHUR, ceres::SPARSE_SCHUR, ceres::DENSE_QR}) {
    options.linear_solver = solver;
    c.ceres.emplace_back(ceres::LinearSolverTypeToString(solver), solveWindowWithCeres(w, options));
  }
  return c;
}

TEST(CeresPeer, SameSolutionAsMarglabF64OnEveryShippedWindow) {
  const std::vector<NamedWindow> windows = loadWindows();
  ASSERT_GE(windows.size(), 4u);
  for (const NamedWindow& nw : windows) {
    SCOPED_TRACE(nw.name);
    WindowSnapshot w = nw.window;
    for (auto& f : w.frames) {
      f.linearized = false;
      f.speed_bias_linearized = false;
    }
    const Converged c = solveToConvergence(w);
    ASSERT_TRUE(c.marglab.result.status.ok());
    const double cost0 = c.marglab.result.cost_initial;
    for (const auto& [solver, r] : c.ceres) {
      SCOPED_TRACE(solver);
      ASSERT_TRUE(r.ok) << r.message;
      // The same energy at the start (summation order only).
      EXPECT_NEAR(r.cost_initial, cost0, 1e-12 * cost0);
      std::string where;
      const double diff = maxRelativeDifference(c.marglab.step, r.step, &where);
      EXPECT_LE(diff, 1e-6) << where;
    }
    // Not trivially equal: the solution is far from the start.
    std::string where;
    EXPECT_GT(maxRelativeDifference(c.marglab.step, startOf(w), &where), 1e-4);
    EXPECT_LT(c.marglab.result.cost_final, 0.99 * cost0);
  }
}

TEST(CeresPeer, WithFirstEstimatesBothStallAtTheSameCost) {
  for (const NamedWindow& nw : loadWindows()) {
    SCOPED_TRACE(nw.name);
    const Converged c = solveToConvergence(nw.window);
    ASSERT_TRUE(c.marglab.result.status.ok());
    const double cost0 = c.marglab.result.cost_initial;
    for (const auto& [solver, r] : c.ceres) {
      SCOPED_TRACE(solver);
      ASSERT_TRUE(r.ok) << r.message;
      EXPECT_NEAR(r.cost_initial, cost0, 1e-12 * cost0);
      // Both endpoints lie in the FEJ stall region; its cost spread is far below the decrease.
      EXPECT_LT(std::abs(r.cost_final - c.marglab.result.cost_final),
                1e-6 * (cost0 - c.marglab.result.cost_final));
    }
  }
}

}  // namespace
}  // namespace marglab
