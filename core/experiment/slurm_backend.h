#pragma once
// The Slurm backend of `marglab sweep` (--backend slurm): the planned runs go to one job array per
// distinct time limit (`sbatch --array`, one task per run, `%jobs` throttle), each task running the
// same `marglab run` command as the local backend in the same sweep folder (shared filesystem);
// the script is kept as slurm/array-<n>.sbatch. index.csv stays the single source of truth: it is
// reconciled from the results files, Slurm's task states (squeue, sacct where accounting exists)
// and, where Slurm has forgotten a task, the exit file its script left (slurm_script.h).
//
// Slurm's outcomes → failure_kind: TIMEOUT/DEADLINE → timeout, CANCELLED/PREEMPTED →
// interrupted, OUT_OF_MEMORY → oom, NODE_FAIL/BOOT_FAIL → node; a task that ended by itself is
// judged like a local run (complete results file → ok / numerical, else exit or signal).
//
// The folder records the binary and git revision that planned it (slurm/binary.txt); a --resume or
// --status by another revision while tasks are still queued is refused, and every task checks the
// binary's revision before it runs. --resume submits only the runs that are neither complete nor
// still queued. Ctrl-C while following cancels the arrays (scancel); the runs become interrupted.

#include <string>
#include <vector>

#include "core/experiment/slurm_reconcile.h"
#include "core/experiment/slurm_script.h"
#include "core/experiment/sweep_def.h"
#include "core/experiment/sweep_index.h"
#include "core/experiment/sweep_runner.h"

namespace marglab::experiment {

// Submits the plan (and follows it with options.slurm.wait); prints like runSweepAndReport and
// returns the same exit codes; 1 when Slurm rejects the submission (its message is printed and the
// folder's index lists the runs as pending, so --resume can submit them again).
int runSlurmSweepAndReport(const SweepPlan& plan, const std::string& sweep_file,
                           const SweepOptions& options);

// `marglab sweep --status DIR [--wait]`: reconciles DIR's index with Slurm and prints where the
// sweep stands; follows it to the end with options.slurm.wait. Exit code as above; 0 while runs
// are still queued.
int slurmSweepStatus(const std::string& dir, const SweepOptions& options);

}  // namespace marglab::experiment
