#pragma once
// Reconciling a sweep's index with Slurm: the rows whose array task is still queued or running
// (status pending / running with a slurm_job) are updated from Slurm's task states (squeue, sacct
// where accounting exists), the exit file the task script leaves (slurm_script.h) and the results
// file. The results file comes first: a run that completed is a result whatever Slurm did after.
// Slurm's endings → failure_kind: TIMEOUT / DEADLINE → timeout, CANCELLED / PREEMPTED →
// interrupted, OUT_OF_MEMORY → oom, NODE_FAIL / BOOT_FAIL → node; a task that ended by itself is
// judged like a local run (exit, or signal when it died by one).

#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "core/experiment/slurm_client.h"
#include "core/experiment/slurm_script.h"
#include "core/experiment/sweep_index.h"

namespace marglab::experiment {

// A row whose task may still run: status pending or running, with a slurm_job.
bool isUnresolvedTask(const IndexRow& row);
// "12_3" → "12".
std::string jobOf(const std::string& task);
// The job ids of the unresolved rows.
std::set<std::string> unresolvedJobs(const std::vector<IndexRow>& rows);

// The row of one finished (or forgotten) task from Slurm's state ("" when Slurm no longer knows
// it), its exit file and its results file (of git revision `revision`). Returns false and only sets
// the status (pending / running) while the task may still run.
bool applyTaskOutcome(const std::string& sweep_dir, const std::string& state, const TaskExit& exit,
                      const std::string& revision, IndexRow* row);

// Brings a folder's unresolved rows up to date with Slurm; one squeue per array.
class SlurmReconciler {
 public:
  SlurmReconciler(std::filesystem::path out, std::string revision)
      : out_(std::move(out)), revision_(std::move(revision)) {}

  // Returns the indices of the rows that finished now.
  std::vector<std::size_t> update(std::vector<IndexRow>* rows) const;

 private:
  std::filesystem::path out_;
  std::string revision_;
  SlurmClient client_;
};

}  // namespace marglab::experiment
