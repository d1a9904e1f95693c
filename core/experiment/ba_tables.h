#pragma once
// The comparison tables of `marglab ba` runs (issue #39, docs/bundle_adjustment.md), made by
// `marglab tables` beside the estimator's tables when a sweep folder holds ba runs (index column
// kind = "ba"). They are not TableSpecs: a TableSpec's cell reduces one column's runs, while these
// cells compare the solvers of one problem and seed with each other (the best cost any of them
// reached, the fastest time to a threshold, the f64 twin) before reducing over the seeds. One set
// of tables per sweep group (one protocol), a row per problem, a column per solver:
//
//   ba_<group>_tau<τ>     rootba's performance profile, τ ∈ {0.1, 0.01, 0.001}: with best the
//                         lowest final cost of any solver on the problem and seed, the time of
//                         the first iteration whose cost ≤ best + τ (initial − best), in seconds
//                         and relative to the fastest solver of that problem and seed; medians over
//                         the seeds that reached it, `x k/n` for the seeds that never did
//   ba_<group>_speedup    the fastest Ceres solver's time to τ = 0.01 over each ns / sc solver's,
//                         per problem and seed; median / min over the seeds (groups with Ceres)
//   ba_<group>_final      final cost, mean ± sample std over the seeds
//   ba_<group>_gap        (final − best) / best, mean / max over the seeds
//   ba_<group>_precision  f32 against its f64 twin (ns-f32 vs ns-f64, sc-f32 vs sc-f64):
//                         (final_f32 − final_f64) / final_f64, mean / max |·| over the seeds
//   ba_<group>_steps      failed steps (the linear solve or the cost failed numerically: an H_ll
//                         not positive definite, a non-finite cost, ...) / rejected steps (the
//                         cost did not decrease), mean over the seeds
//   ba_<group>_conditioning  κ = ritz_max / ritz_min of the preconditioned reduced camera system
//                         from CG, median over the run's iterations / its maximum, median over
//                         the seeds (ns / sc only: Ceres reports none)
//   ba_<group>_memory     peak resident memory [MB] / total solve time [s], medians over seeds
//
// A run whose results file is not in its folder (a committed folder without runs/) is read from
// its index row: final cost, initial cost, time and memory; the tables that need /iterations
// (tau, steps, conditioning) leave its cells out (`–`).

#include <cstdint>
#include <string>
#include <vector>

#include "core/ba/ba_results.h"
#include "core/experiment/tables.h"

namespace marglab::experiment {

struct BaRunData {
  std::string dir, group, problem, solver;
  std::uint64_t seed = 0;
  bool failed = false;    // the solver's status "failed" (a result: its costs are still there)
  bool has_file = false;  // `file` read from the results file, else the index row's values only
  BaResultsFile file;
};

// The finished ba runs (status ok or failed) of the folders' indexes; warnings for runs listed ok
// whose results file cannot be read and whose index row holds no final cost.
std::vector<BaRunData> loadBaRuns(const std::vector<std::string>& dirs,
                                  std::vector<std::string>* warnings);

// The tables above, per group in the order of first appearance; why a table is absent in
// *skipped.
std::vector<Table> buildBaTables(const std::vector<BaRunData>& runs,
                                 std::vector<std::string>* skipped);

// The performance profile's time of one run: its first iteration with cost ≤ threshold (+inf
// when none).
double timeToCost(const BaResultsFile& run, double threshold);

}  // namespace marglab::experiment
