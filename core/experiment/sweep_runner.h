#pragma once
// Executes a sweep plan: every run is a child process (fork + exec of the marglab binary, verb
// `run`) with its own log, so that a crash — even SIGKILL — only fails that run. The sweep folder:
//
//   <out>/index.csv          one row per planned run (sweep_index.h), rewritten atomically
//   <out>/sweep.toml         a copy of the sweep file that was run
//   <out>/runs/<id>.h5       results file (docs/design.md §6; absent unless complete) + <id>.tum
//   <out>/runs/<id>.cmd      the run's fingerprint: its command line and config overrides
//   <out>/configs/<id>.toml  config overrides of the run (only when it has some)
//   <out>/logs/<id>.log      stdout and stderr of the run
//
//   <out>/.lock              the folder's lock (sweep_common.h, SweepLock): one sweep at a time
//
// Runs start in <out>, so the index's `command` column can be pasted there to repeat one run.
// They die with the sweep (core/common/subprocess.h): a killed sweep leaves no orphan run behind.
// The `frontend = "images"` datasets are tracked first, once each (`marglab datasets track` into
// <out>/tracks/<dataset slug>.h5, its output in <out>/logs/tracks_<dataset slug>.log); a dataset
// whose tracking fails fails its runs (failure_kind error) and the others go on.
// Longest runs (by frames) start first. Scheduling order does not change any result: each run
// is deterministic for its seed.
//
// --resume keeps a run whose results file is complete (opens as a results file with a status
// attribute, ok or failed), was written by this build's git revision (attribute git_sha) and whose
// fingerprint equals the planned one; everything else —
// missing, partial (a killed run leaves at most a temporary, which is removed), crashed, or planned
// differently — is run again. A numerically failed run (status failed in a complete file) is a
// result, not a crash: it is deterministic and kept.

#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "core/experiment/sweep_def.h"
#include "core/experiment/sweep_index.h"

namespace marglab::experiment {

// Backend slurm (slurm_backend.h): the runs go to a Slurm job array instead of local children.
struct SlurmOptions {
  std::string partition;           // --partition; "" = the cluster's default
  std::string time;                // --time for every task; "" = from the group's timeout_s
  std::string mem;                 // --mem, e.g. "4G"; "" = the cluster's default
  int cpus = 1;                    // --cpus-per-task (a run is single-threaded)
  std::vector<std::string> extra;  // further #SBATCH options, verbatim ("--qos=long")
  bool wait = false;               // follow the array until it ends
  double poll_s = 2;               // seconds between squeue polls while following
};

struct SweepOptions {
  std::string out_dir;
  int jobs = 0;              // 0: number of cores
  bool resume = false;       // keep complete runs of an earlier invocation
  bool force = false;        // discard an earlier sweep in out_dir (runs, logs, configs, index)
  std::string executable;    // marglab binary; "" = /proc/self/exe
  bool status_line = false;  // live status line on stderr (a terminal); else one line per run
  std::FILE* out = stdout;   // per-run lines and the final summary
  std::string backend = "local";  // local | slurm
  SlurmOptions slurm;
};

struct SweepSummary {
  int planned = 0;
  int ok = 0;
  FailureCounts failed;           // the failed runs by category (sweep_index.h)
  int reused = 0;                 // kept by --resume
  int not_run = 0;                // still pending after an interruption
  int redone_other_revision = 0;  // complete, but written by another git revision: run again
  bool interrupted = false;
  int stop_signal = 0;  // the SIGINT / SIGTERM that interrupted the sweep
  double wall_s = 0;
  std::string index_path;
};

// Throws UsageError when out_dir holds another sweep and neither resume nor force is set;
// InputError when files cannot be written.
SweepSummary runSweep(const SweepPlan& plan, const std::string& sweep_file_text,
                      const SweepOptions& options);

// runSweep with the file's text, printing a header and the summary to options.out; returns the exit
// code of `marglab sweep`: 0 (numerical failures are results), 1 when a run crashed or was
// killed, 128 + the signal when interrupted (130 for SIGINT, 143 for SIGTERM). With
// options.backend "slurm" the Slurm backend runs the plan instead (runSlurmSweepAndReport,
// slurm_backend.h).
int runSweepAndReport(const SweepPlan& plan, const std::string& sweep_file,
                      const SweepOptions& options);

// The fingerprint stored in runs/<id>.cmd.
std::string runFingerprint(const PlannedRun& run);

// A command line with shell quoting where needed.
std::string shellJoin(const std::vector<std::string>& args);

}  // namespace marglab::experiment
