// The comparison tables of `marglab ba` runs (core/experiment/ba_tables.h) on synthetic runs whose
// every cell is computed here by hand: the performance profile's thresholds, times and ratios, the
// f32-vs-f64 gap, failed and rejected steps, the Ritz conditioning, and seeds that never reach a
// threshold counted as `x k/n`.

#include <gtest/gtest.h>

#include <cmath>

#include "core/experiment/ba_tables.h"

namespace marglab::experiment {
namespace {

// A run whose cost falls along `costs` at times 0, 1, 2, ... seconds.
BaRunData run(const std::string& solver, std::uint64_t seed, std::vector<double> costs,
              std::vector<bool> accepted = {}, std::vector<std::string> messages = {}) {
  BaRunData r;
  r.group = "g";
  r.problem = "p";
  r.solver = solver;
  r.seed = seed;
  r.has_file = true;
  r.file.problem = "p";
  r.file.solver = solver;
  r.file.initial_cost = costs.front();
  r.file.final_cost = costs.back();
  r.file.peak_rss_mb = 10;
  r.file.total_time_s = static_cast<double>(costs.size() - 1);
  for (std::size_t i = 0; i < costs.size(); ++i) {
    BaIteration it;
    it.iteration = static_cast<int>(i);
    it.cost = costs[i];
    it.time_s = static_cast<double>(i);
    it.accepted = accepted.empty() ? true : accepted[i];
    it.message = messages.empty() ? "" : messages[i];
    it.ritz_min = solver.rfind("ceres", 0) == 0 ? NAN : 1.0;
    it.ritz_max = solver.rfind("ceres", 0) == 0 ? NAN : 10.0 * static_cast<double>(i + 1);
    r.file.iterations.push_back(it);
  }
  return r;
}

const Table& tableOf(const std::vector<Table>& tables, const std::string& id) {
  for (const Table& t : tables) {
    if (t.id == id) return t;
  }
  throw std::runtime_error("no table " + id);
}

const TableCell& cellOf(const Table& t, const std::string& column) {
  for (std::size_t c = 0; c < t.columns.size(); ++c) {
    if (t.columns[c].variant == column) return t.rows.at(0).ours.at(c);
  }
  throw std::runtime_error("no column " + column);
}

TEST(BaTables, ProfileThresholdsTimesAndRatiosByHand) {
  // Seed 1: best = 10 (ns-f64). τ = 0.1: threshold 10 + 0.1 (100 − 10) = 19 (every run starts at
  // 100). ns-f32 reaches 18 at 2 s, ns-f64 15 at 1 s, ceres-sparse 19 at 3 s.
  // Seed 2: best = 20 (ceres-sparse); threshold 28; ns-f32 reaches 25 at 1 s, ns-f64 never, ceres
  // 28 at 2 s.
  std::vector<BaRunData> runs = {run("ns-f32", 1, {100, 50, 18, 12, 11}),
                                 run("ns-f64", 1, {100, 15, 12, 10, 10}),
                                 run("ceres-sparse", 1, {100, 60, 40, 19, 10.5}),
                                 run("ns-f32", 2, {100, 25, 24, 22, 21}),
                                 run("ns-f64", 2, {100, 90, 80, 70, 60}),
                                 run("ceres-sparse", 2, {100, 40, 28, 21, 20})};
  std::vector<std::string> skipped;
  const std::vector<Table> tables = buildBaTables(runs, &skipped);
  const Table& tau = tableOf(tables, "ba_g_tau0.1");
  ASSERT_EQ(tau.columns.size(), 3u);
  EXPECT_EQ(tau.columns[0].variant, "ns-f32");  // `marglab ba`'s order
  EXPECT_EQ(tau.columns[2].variant, "ceres-sparse");
  // ns-f32: 2 s (×2 of ns-f64's 1 s) and 1 s (×1): medians 1.5 s and ×1.5.
  const TableCell& f32 = cellOf(tau, "ns-f32");
  ASSERT_EQ(f32.state, TableCell::State::kValue);
  EXPECT_DOUBLE_EQ(f32.numbers[0], 1.5);
  EXPECT_DOUBLE_EQ(f32.numbers[1], 1.5);
  // ns-f64: 1 s (×1) on seed 1, never on seed 2: x 1/2 beside the one value.
  const TableCell& f64 = cellOf(tau, "ns-f64");
  EXPECT_DOUBLE_EQ(f64.numbers[0], 1.0);
  EXPECT_DOUBLE_EQ(f64.numbers[1], 1.0);
  EXPECT_EQ(f64.n_failed, 1);
  EXPECT_EQ(f64.n_runs, 2);
  // ceres-sparse: 3 s (×3) and 2 s (×2).
  EXPECT_DOUBLE_EQ(cellOf(tau, "ceres-sparse").numbers[0], 2.5);
  EXPECT_DOUBLE_EQ(cellOf(tau, "ceres-sparse").numbers[1], 2.5);

  // Against the fastest Ceres solver at τ = 0.01 (thresholds 10.9 and 20.8): ceres-sparse reaches
  // them at 4 s on both seeds; ns-f32 never gets below 11 and 21 (x 2/2), ns-f64 at 3 s on seed 1
  // (4/3) and never on seed 2.
  const Table& speedup = tableOf(tables, "ba_g_speedup");
  ASSERT_EQ(speedup.columns.size(), 2u);
  EXPECT_EQ(cellOf(speedup, "ns-f32").state, TableCell::State::kFailed);
  EXPECT_EQ(cellOf(speedup, "ns-f32").n_failed, 2);
  EXPECT_DOUBLE_EQ(cellOf(speedup, "ns-f64").numbers[0], 4.0 / 3.0);
  EXPECT_EQ(cellOf(speedup, "ns-f64").n_failed, 1);

  // Gap to best: ns-f32 (11 − 10)/10 and (21 − 20)/20.
  const TableCell& gap = cellOf(tableOf(tables, "ba_g_gap"), "ns-f32");
  EXPECT_DOUBLE_EQ(gap.numbers[0], 0.5 * (0.1 + 0.05));
  EXPECT_DOUBLE_EQ(gap.numbers[1], 0.1);
  // f32 against f64: (11 − 10)/10 and (21 − 60)/60; no sc runs: that column is missing.
  const Table& precision = tableOf(tables, "ba_g_precision");
  const TableCell& ns = cellOf(precision, "ns");
  EXPECT_DOUBLE_EQ(ns.numbers[0], 0.5 * (0.1 + (21.0 - 60.0) / 60.0));
  EXPECT_DOUBLE_EQ(ns.numbers[1], 39.0 / 60.0);
  EXPECT_EQ(cellOf(precision, "sc").state, TableCell::State::kMissing);
  // Final cost: mean ± sample std of 11 and 21.
  const TableCell& final_cost = cellOf(tableOf(tables, "ba_g_final"), "ns-f32");
  EXPECT_DOUBLE_EQ(final_cost.numbers[0], 16.0);
  EXPECT_DOUBLE_EQ(final_cost.spread[0], std::sqrt(50.0));
}

TEST(BaTables, StepsConditioningAndANeverReachedThreshold) {
  std::vector<BaRunData> runs = {
      run("sc-f32", 1, {100, 100, 100, 40, 40}, {true, false, false, true, false},
          {"", "H_ll not positive definite", "", "", ""}),
      run("sc-f64", 1, {100, 30, 20, 10, 10}), run("ceres-implicit", 1, {100, 30, 20, 10, 10}),
      run("nsx-f32", 1, {100, 30, 20, 12, 12}), run("nsx-f64", 1, {100, 30, 20, 16, 16})};
  std::vector<std::string> skipped;
  const std::vector<Table> tables = buildBaTables(runs, &skipped);
  const TableCell& steps = cellOf(tableOf(tables, "ba_g_steps"), "sc-f32");
  EXPECT_DOUBLE_EQ(steps.numbers[0], 1.0);  // failed: the one with a message
  EXPECT_DOUBLE_EQ(steps.numbers[1], 2.0);  // rejected: the two without
  // κ per iteration 10 (i + 1) for i = 0..4: median 30, max 50; Ceres has no Ritz values.
  const Table& conditioning = tableOf(tables, "ba_g_conditioning");
  EXPECT_DOUBLE_EQ(cellOf(conditioning, "sc-f32").numbers[0], 30.0);
  EXPECT_DOUBLE_EQ(cellOf(conditioning, "sc-f32").numbers[1], 50.0);
  EXPECT_EQ(cellOf(conditioning, "ceres-implicit").state, TableCell::State::kMissing);
  // τ = 0.1: threshold 10 + 9 = 19; sc-f32 never gets below 40: failed on its only seed.
  const TableCell& never = cellOf(tableOf(tables, "ba_g_tau0.1"), "sc-f32");
  EXPECT_EQ(never.state, TableCell::State::kFailed);
  EXPECT_EQ(never.n_failed, 1);
  EXPECT_EQ(formatCell(never, 0, 3, ""), "x");
  // The f32-vs-f64 table: sc (40 − 10)/10; nsx paired with nsx-f64, (12 − 16)/16; no ns runs.
  EXPECT_DOUBLE_EQ(cellOf(tableOf(tables, "ba_g_precision"), "sc").numbers[0], 3.0);
  EXPECT_DOUBLE_EQ(cellOf(tableOf(tables, "ba_g_precision"), "nsx").numbers[0], -0.25);
  EXPECT_EQ(cellOf(tableOf(tables, "ba_g_precision"), "ns").state, TableCell::State::kMissing);
}

TEST(BaTables, RunsWithoutFilesGiveOnlyWhatTheIndexHolds) {
  BaRunData a = run("ns-f32", 1, {100, 10});
  BaRunData b = run("ns-f64", 1, {100, 12});
  for (BaRunData* r : {&a, &b}) {
    r->has_file = false;
    r->file.iterations.clear();
  }
  std::vector<std::string> skipped;
  const std::vector<Table> tables = buildBaTables({a, b}, &skipped);
  EXPECT_DOUBLE_EQ(cellOf(tableOf(tables, "ba_g_gap"), "ns-f64").numbers[0], 0.2);
  for (const Table& t : tables) {
    EXPECT_EQ(t.id.find("tau"), std::string::npos) << t.id;
    EXPECT_NE(t.id, "ba_g_steps");
  }
  EXPECT_EQ(skipped.size(), 5u);  // the three τ, steps, conditioning
}

TEST(BaTables, TimeToCostIsTheFirstIterationAtOrBelow) {
  const BaRunData r = run("ns-f32", 1, {100, 50, 20, 20, 5});
  EXPECT_EQ(timeToCost(r.file, 20), 2.0);
  EXPECT_EQ(timeToCost(r.file, 100), 0.0);
  EXPECT_TRUE(std::isinf(timeToCost(r.file, 1)));
}

}  // namespace
}  // namespace marglab::experiment
