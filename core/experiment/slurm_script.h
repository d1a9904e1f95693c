#pragma once
// The sbatch script of a sweep's Slurm job array, and the exit file each of its tasks leaves.
//
// One array task per planned run: the script maps SLURM_ARRAY_TASK_ID to the run's id and its
// exact `marglab run` arguments (the same command the local backend runs), starts in the sweep
// folder (shared filesystem), appends the run's output to logs/<id>.log and refuses to run when the
// binary at the recorded path is no longer the revision that planned the sweep (a rebuild between
// submission and start would otherwise mix revisions in one folder). Every task writes
// slurm/exit/<id> when it ends — also on SIGTERM (time limit, scancel) — so that the outcome of a
// task can be read where Slurm has forgotten the job and there is no accounting (sacct):
//   exit=CODE|signal=TERM start=EPOCH_S end=EPOCH_S job=JOBID_TASK host=NODE
// A task may be another marglab verb than `run`: the image front-end of a `frontend = "images"`
// dataset is tracked once by a one-task array (`datasets track`, id tracks_<dataset slug>, so its
// log is logs/tracks_<dataset slug>.log as with the local backend) that the run arrays depend on.

#include <string>
#include <vector>

namespace marglab::experiment {

struct SlurmTask {
  std::string id;                 // run id
  std::vector<std::string> args;  // `marglab run ...` arguments, without the program
};

struct SlurmArraySpec {
  std::string sweep_name;
  std::string sweep_dir;   // absolute; the tasks start here
  std::string executable;  // absolute path of the marglab binary
  std::string revision;    // its git revision (MARGLAB_GIT_SHA)
  std::string time;        // --time ("" : none, the partition's default)
  int throttle = 0;        // --array=...%throttle, 0: none
  std::string partition;   // "" : the default partition
  std::string mem;         // "" : the default
  int cpus = 1;
  std::vector<std::string> extra;  // verbatim #SBATCH options
  // Jobs that must end successfully before any task starts (--dependency=afterok); a task whose
  // dependency failed is cancelled by Slurm (--kill-on-invalid-dep) instead of waiting forever.
  std::vector<std::string> after_ok;
  std::vector<SlurmTask> tasks;
};

// The script text (bash, #SBATCH directives for every option).
std::string sbatchScript(const SlurmArraySpec& spec);

// --time of a group: its timeout_s rounded up to whole minutes (Slurm's unit), "" for none.
std::string slurmTimeForTimeout(double timeout_s);

struct TaskExit {
  bool present = false;
  int exit_code = -1;  // -1 when the task ended by a signal
  std::string signal;  // "TERM" when it did
  double start = 0;    // epoch seconds
  double end = 0;
  std::string job;  // JOBID_TASK
};

// Parses slurm/exit/<id>; present = false when missing or unreadable.
TaskExit readTaskExit(const std::string& path);

}  // namespace marglab::experiment
