#pragma once
// The results of one `marglab ba` run (docs/bundle_adjustment.md §Results).
//
// HDF5 file, written atomically (core/io/hdf5.h: nothing at the path until complete):
//   root attributes   kind = "ba", schema_version, marglab_version, git_sha, created_utc; the
//                     problem (problem, problem_file, num_cameras, num_points, num_observations);
//                     the settings (solver, precision, iterations, huber_px, perturb_sigma, seed,
//                     normalize_scale, initial_lambda, min_lambda, max_lambda, function_tolerance,
//                     cg_max_iterations, cg_eta, threads); the outcome (initial_cost, final_cost,
//                     status, status_reason, num_behind_initial, num_behind_final,
//                     num_fixed_points, total_time_s, total_cpu_s, peak_rss_mb)
//   /iterations       one row per LM trial (row 0: the initial cost): iteration, cost (after the
//                     trial: the current cost, unchanged by a rejected step), time_s, cpu_s
//                     (the process's CPU time, all threads), lambda,
//                     cg_iterations, accepted (0/1), ritz_min, ritz_max (NaN where not
//                     available); attribute `messages` (one string per row, "" or why the step
//                     failed).
// JSON (--json): {"problem", "solver", "status", "status_reason", "initial_cost", "final_cost",
// "total_time_s", "peak_rss_mb", "iterations": [{"cost", "time_s"}, ...]}.

#include <string>

#include "core/ba/ba_options.h"
#include "core/ba/bal_problem.h"
#include "core/common/json.h"

namespace marglab {

struct BaRunRecord {
  std::string problem_file;
  const BalProblem* problem = nullptr;
  BaOptions options;
  BaResult result;
  double peak_rss_mb = 0;
};

void writeBaResults(const std::string& path, const BaRunRecord& run);
Json baResultJson(const BaRunRecord& run);

// A ba results file as read back (by the sweep's index and resume, and by `marglab tables`).
struct BaResultsFile {
  std::string git_sha, problem, problem_file, solver, precision, status, status_reason;
  std::string isa;  // the kernels' ISA ("" in files written before it was recorded)
  int num_cameras = 0, num_points = 0, num_observations = 0;
  int max_iterations = 0, threads = 1;
  std::uint64_t seed = 0;
  double huber_px = 0, perturb_sigma = 0, normalize_scale = 0;
  double initial_cost = 0, final_cost = 0, total_time_s = 0, peak_rss_mb = 0;
  std::vector<BaIteration> iterations;  // /iterations, row 0 the initial cost
};
// Reads one through the trust boundary (core/io/hdf5_trust.h); InputError naming the file when it
// is not a complete ba results file.
BaResultsFile readBaResults(const std::string& path);

// Peak resident set size of this process so far (getrusage), in MB.
double peakResidentMb();

}  // namespace marglab
