#pragma once
// The index of a sweep: results/<name>/index.csv, one row per planned run, rewritten atomically
// (temporary + rename) whenever a run starts or ends, so that a reader (pandas, `marglab tables`,
// `marglab plot`, `sweep --resume`) never sees a half-written index.
//
// Columns (paths relative to the sweep folder; empty cells for unknown values):
//   id, group, dataset, variant, method, precision, seed, frames (requested, 0: all), override,
//   status        pending | running | ok | failed
//   failure_kind  "" | numerical (the estimator failed: complete results file, status failed) |
//                 tracking (the run lost the scene: complete results file, status failed) |
//                 signal | exit (the process died / exited without a complete results file) |
//                 timeout | interrupted (the sweep was stopped, or the Slurm task cancelled) |
//                 error (could not start) | oom (Slurm: out of memory) | node (Slurm: node failure)
//   failure_frame, reason, exit_code, signal,
//   reused        1 when --resume kept a complete results file from an earlier invocation
//   wall_s        wall time of the `marglab run` process (simulation and diagnostics included)
//   n_frames, ate_rmse, duration_s, t_opt_total_s, t_marg_total_s, wall_time_s, realtime_factor
//                 copied from the results file's /summary (%.17g; `marglab tables` reads the
//                 HDF5 when it is there, these columns when it is not)
//   mode          the results file's estimator mode (vo | vio), copied with the summary
//   results, log, config, command (the exact `marglab run` command line), pid,
//   slurm_job     JOBID_TASK of the run's Slurm array task (backend slurm), started_utc
// and, only in the index of a sweep with `marglab ba` runs (a group of kind "ba"), after those:
//   kind          "ba" for a ba run ("" for a `marglab run` run)
//   ba_status     the solver's status: converged | max_iterations | no_convergence | failed
//                 (status ok for the first three; failed is failure_kind numerical)
//   initial_cost, final_cost, total_time_s, peak_rss_mb   copied from the ba results file

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/common/atomic_file.h"  // writeFileAtomically, for the index and the tables

namespace marglab::experiment {

struct IndexRow {
  std::map<std::string, std::string> values;  // column → cell text

  const std::string& get(const std::string& column) const;  // "" when absent
  void set(const std::string& column, const std::string& value) { values[column] = value; }
  void setNumber(const std::string& column, double value);  // %.17g; "" for NaN
  // The cell as a number; NaN when empty or not a number.
  double number(const std::string& column) const;
};

// The failed runs of a sweep in the categories of its summary line, from their failure_kind:
// results of the sweep — the estimator failed numerically (numerical) or lost the scene
// (tracking) —; runs that ended with an error they reported (error: could not start, or the
// images could not be tracked; exit with code 1 or 2: an input, usage or write error, the message
// in reason); runs that crashed or were killed (signal, timeout, interrupted, oom, node, any other
// exit), counted per kind.
struct FailureCounts {
  int numerical = 0;
  int tracking = 0;
  int error = 0;
  int crashed = 0;
  std::map<std::string, int> crashed_kinds;  // failure_kind → runs

  void add(const IndexRow& row);  // a row with status failed
  // Failures of the sweep's processes (its exit code 1), not results.
  int processFailures() const { return error + crashed; }
  // "M failed numerically[, L lost tracking][, E ended with an error], K crashed or killed
  // [(n kind, …)]": the categories that no run is in are left out, but for the first and last.
  std::string text() const;
};

// The column order of index.csv; the ba columns follow when some row is a ba run.
const std::vector<std::string>& indexColumns();
const std::vector<std::string>& baIndexColumns();

// Writes the rows as CSV (RFC 4180 quoting) through `path`.tmp + rename.
void writeIndex(const std::string& path, const std::vector<IndexRow>& rows);
// Reads an index.csv; throws InputError(path, line, what) on malformed CSV.
std::vector<IndexRow> readIndex(const std::string& path);

// CSV helpers (shared with the tables' CSV output).
std::string csvField(const std::string& value);
std::vector<std::vector<std::string>> parseCsv(const std::string& text, const std::string& name);

}  // namespace marglab::experiment
