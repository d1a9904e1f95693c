#include "core/experiment/slurm_reconcile.h"

#include <fmt/core.h>

#include <csignal>
#include <ctime>

#include "core/experiment/sweep_common.h"

namespace marglab::experiment {

namespace fs = std::filesystem;

bool isUnresolvedTask(const IndexRow& row) {
  const std::string& status = row.get("status");
  return !row.get("slurm_job").empty() && (status == "pending" || status == "running");
}

std::string jobOf(const std::string& task) { return task.substr(0, task.find('_')); }

std::set<std::string> unresolvedJobs(const std::vector<IndexRow>& rows) {
  std::set<std::string> jobs;
  for (const IndexRow& row : rows) {
    if (isUnresolvedTask(row)) jobs.insert(jobOf(row.get("slurm_job")));
  }
  return jobs;
}

namespace {

std::string isoUtc(double epoch_s) {
  const std::time_t t = static_cast<std::time_t>(epoch_s);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buffer[32];
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buffer;
}

// failure_kind and reason of a task that Slurm ended; empty kind when the task ended by itself.
std::pair<std::string, std::string> slurmEnding(const std::string& state) {
  if (state == "TIMEOUT" || state == "DEADLINE") return {"timeout", "Slurm's time limit reached"};
  if (state == "CANCELLED") return {"interrupted", "cancelled in Slurm (scancel)"};
  if (state == "PREEMPTED") return {"interrupted", "preempted by Slurm"};
  if (state == "OUT_OF_MEMORY") return {"oom", "killed by Slurm: out of memory"};
  if (state == "NODE_FAIL" || state == "BOOT_FAIL") return {"node", "node failure (" + state + ")"};
  return {};
}

// A task that ended by itself without a complete results file: like a local run's exit.
void setProcessFailure(const fs::path& out, const std::string& state, const TaskExit& exit,
                       IndexRow* row) {
  const std::string task = row->get("slurm_job");
  const std::string log = (out / row->get("log")).string();
  if (!exit.present) {
    row->set("failure_kind", "exit");
    row->set("reason", state.empty()
                           ? "Slurm no longer knows task " + task +
                                 " and it left no exit file (no accounting to ask)"
                           : "task " + task + " ended " + state +
                                 " without an exit file: " + detail::lastNonEmptyLine(log));
  } else if (!exit.signal.empty() || exit.exit_code > 128) {
    const int sig = exit.signal.empty() ? exit.exit_code - 128 : SIGTERM;
    row->set("failure_kind", "signal");
    row->set("signal", std::to_string(sig));
    row->set("reason", "killed by " + detail::signalName(sig) + " (task " + task + ")");
  } else {
    row->set("failure_kind", "exit");
    row->set("reason", fmt::format("exit code {} without a complete results file: {}",
                                   exit.exit_code, detail::lastNonEmptyLine(log)));
  }
}

}  // namespace

bool applyTaskOutcome(const std::string& sweep_dir, const std::string& state, const TaskExit& exit,
                      const std::string& revision, IndexRow* row) {
  if (isActiveState(state)) {
    row->set("status", isPendingState(state) ? "pending" : "running");
    return false;
  }
  const fs::path out(sweep_dir);
  detail::removeTemporaries(out / row->get("results"));  // a killed writer's leftovers
  if (exit.present) {
    row->setNumber("wall_s", exit.end - exit.start);
    row->set("started_utc", isoUtc(exit.start));
    if (exit.exit_code >= 0) row->set("exit_code", std::to_string(exit.exit_code));
  }
  // The results file first: a run that completed is a result whatever Slurm did afterwards.
  if (detail::readCompleteResults((out / row->get("results")).string(), row, revision.c_str())) {
    return true;
  }
  row->set("status", "failed");
  const auto [kind, why] = slurmEnding(state);
  if (kind.empty()) {
    setProcessFailure(out, state, exit, row);
  } else {
    row->set("failure_kind", kind);
    row->set("reason", why + " (task " + row->get("slurm_job") + ")");
  }
  return true;
}

std::vector<std::size_t> SlurmReconciler::update(std::vector<IndexRow>* rows) const {
  const std::set<std::string> jobs = unresolvedJobs(*rows);
  if (jobs.empty()) return {};
  bool query_failed = false;
  const TaskStates states = client_.taskStates(jobs, &query_failed);
  std::vector<std::size_t> finished;
  for (std::size_t i = 0; i < rows->size(); ++i) {
    IndexRow& row = (*rows)[i];
    if (!isUnresolvedTask(row)) continue;
    const auto it = states.find(row.get("slurm_job"));
    // Not listed because the controller did not answer is not "forgotten": ask again later.
    if (it == states.end() && query_failed) continue;
    const TaskExit exit = readTaskExit((out_ / "slurm" / "exit" / row.get("id")).string());
    const std::string state = it == states.end() ? "" : it->second;
    if (applyTaskOutcome(out_.string(), state, exit, revision_, &row)) finished.push_back(i);
  }
  return finished;
}

}  // namespace marglab::experiment
