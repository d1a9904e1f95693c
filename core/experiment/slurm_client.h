#pragma once
// The Slurm commands the sweep's Slurm backend needs, run as child processes (no shell, no
// library: a lab's login node has the client commands but rarely the development headers):
//   sbatch --parsable SCRIPT          submit a job array; stdout "JOBID[;CLUSTER]"
//   squeue -h -r -t all -j JOB        every task of the array, finished ones included while
//                                     slurmctld still keeps them (MinJobAge)
//   sacct -n -P -X -j JOB             the same from accounting, where a slurmdbd exists
//   scancel JOB | JOB_TASK            cancel the array or one task
//   sinfo                             does a cluster answer at all

#include <map>
#include <set>
#include <string>
#include <vector>

#include "core/common/subprocess.h"  // runCommand

namespace marglab::experiment {

// A task's state as Slurm names it (PENDING, RUNNING, COMPLETED, FAILED, TIMEOUT, CANCELLED,
// OUT_OF_MEMORY, NODE_FAIL, ...), per "JOBID_TASK".
using TaskStates = std::map<std::string, std::string>;

class SlurmClient {
 public:
  // Submits the script; returns the job id. Throws InputError(script, 0, sbatch's message) when
  // Slurm rejects it (unknown partition, time above the limit, ...).
  std::string submit(const std::string& script_path) const;

  // The states of every task of these jobs that squeue or sacct still knows. A job neither knows
  // (purged, no accounting) is absent; *query_failed is set when a command failed for another
  // reason (controller down), so that absent tasks are not taken as lost.
  TaskStates taskStates(const std::set<std::string>& job_ids, bool* query_failed) const;

  // scancel of jobs or single tasks ("JOBID" or "JOBID_TASK"); false with the message on failure.
  bool cancel(const std::vector<std::string>& ids, std::string* message) const;

  // Whether a controller answers (sinfo); else why not.
  static bool available(std::string* why);
};

// "RUNNING" → true for states in which the task may still run or start.
bool isActiveState(const std::string& state);
bool isPendingState(const std::string& state);

}  // namespace marglab::experiment
