#pragma once
// What every sweep backend (the local child processes of sweep_runner.cpp, the Slurm job array of
// slurm_backend.cpp) does the same way, so that a sweep folder means the same whichever backend
// filled it: the folder layout, the index row of a planned run, the --resume decision (complete
// results file of this revision, same fingerprint), the files written before a run starts, and the
// reading of a finished run's results file.

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/experiment/sweep_def.h"
#include "core/experiment/sweep_index.h"

namespace marglab::experiment::detail {

std::string readTextFile(const std::string& path);  // "" when missing
// The last non-blank line of a log (a progress line overwritten with \r: its last state).
std::string lastNonEmptyLine(const std::string& path);
std::string formatDuration(double seconds);  // m:ss or h:mm:ss; --:-- when unknown
std::string signalName(int signal);          // "SIGKILL (Killed)"

// Is this a complete results file? Fills the row's status and summary columns when it is. With
// git_sha, only a file written by that revision counts (so --resume never mixes revisions).
bool readCompleteResults(const std::string& path, IndexRow* row, const char* git_sha = nullptr,
                         bool* other_revision = nullptr);

// A finished row's outcome, as the per-run line prints it: "ATE 0.1234 m", a ba run's
// "cost 7.648565e+03 (max_iterations)", or "<failure_kind>[ at frame N]: <reason>".
std::string outcomeText(const IndexRow& row);

// Empties the outcome columns of a row that is about to run (again).
void clearOutcome(IndexRow* row);
// A failed run whose results file is complete — the estimator failed numerically or lost the scene
// (failure_kind "numerical" | "tracking"): a result of the sweep, not a failure of its processes.
bool isFailedResult(const IndexRow& row);

// Removes what a killed writer may leave behind: <results>.tmp-<pid>-<n>.
void removeTemporaries(const std::filesystem::path& results);

// The sweep folder's advisory lock: flock(2) on <out>/.lock, held while the object lives, so that
// two sweeps never fill one folder at once (each would remove the other's temporaries and
// rewrite its index). The file holds the owner's "pid <PID> host <HOST> since <UTC>" for the
// message of a second sweep, which throws InputError naming them. The kernel releases the lock
// when its owner dies, even by SIGKILL, so a stale lock is taken over without any check; the file
// stays (removing it would let two processes lock different files). Descriptors are close-on-exec:
// the runs never hold the lock.
class SweepLock {
 public:
  explicit SweepLock(const std::filesystem::path& out);
  ~SweepLock();
  SweepLock(const SweepLock&) = delete;
  SweepLock& operator=(const SweepLock&) = delete;

 private:
  int fd_ = -1;
};

// The index of the marglab sweep in `out` (which has an index.csv). Throws InputError naming the
// file when the folder is not one marglab wrote: no sweep.toml beside the index, or an index that
// is not a sweep index (malformed, or without the columns id, status, results, log, command).
std::vector<IndexRow> readOwnSweepIndex(const std::filesystem::path& out);

// Creates the folder (runs/, logs/, configs/, sweep.toml); with force, removes the earlier sweep's
// files (those its index lists, its track files and Slurm scripts; nothing else). Throws
// UsageError when out holds a sweep and neither resume nor force is set; InputError when out
// holds an index.csv that is not a marglab sweep's (readOwnSweepIndex), whatever the flags.
void prepareSweepFolder(const std::filesystem::path& out, const std::string& sweep_file_text,
                        bool resume, bool force);

// The index row of a planned run (status empty): ids, paths and the exact command.
IndexRow plannedRow(const PlannedRun& run);

// --resume: keeps the row's earlier result when its results file is complete, of this build's
// revision and planned identically (runs/<id>.cmd). Sets *other_revision when the file is complete
// but of another revision.
bool keepEarlierResult(const std::filesystem::path& out, const PlannedRun& run, IndexRow* row,
                       bool* other_revision);

// Before a run starts: removes an earlier attempt's results, writes its config, fingerprint and log
// header, and clears the row's outcome.
void prepareRunFiles(const std::filesystem::path& out, const std::string& sweep_name,
                     const PlannedRun& run, IndexRow* row);

// Frames a run will process, for ordering and the ETA (the sequence length when not limited).
class FrameEstimator {
 public:
  double operator()(const PlannedRun& run);

 private:
  std::map<std::string, double> cache_;
};

}  // namespace marglab::experiment::detail
