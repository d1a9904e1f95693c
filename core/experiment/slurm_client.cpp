#include "core/experiment/slurm_client.h"

#include <sstream>

#include "core/common/error.h"
#include "core/common/subprocess.h"

namespace marglab::experiment {
namespace {

std::string trim(const std::string& text) {
  const auto a = text.find_first_not_of(" \t\r\n");
  const auto b = text.find_last_not_of(" \t\r\n");
  return a == std::string::npos ? "" : text.substr(a, b - a + 1);
}

// "JOBID_TASK|STATE..." lines of squeue / sacct into states; ranges of pending tasks
// ("12_[3-5]") are skipped: squeue -r lists each task, sacct shows started ones.
void parseStates(const std::string& text, TaskStates* states) {
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    const auto bar = line.find('|');
    if (bar == std::string::npos) continue;
    const std::string id = trim(line.substr(0, bar));
    std::string state = trim(line.substr(bar + 1));
    state = state.substr(0, state.find_first_of(" |+"));  // "CANCELLED by 0", "CANCELLED+"
    if (id.find('[') != std::string::npos || id.find('_') == std::string::npos) continue;
    if (!states->count(id)) (*states)[id] = state;
  }
}

}  // namespace

std::string SlurmClient::submit(const std::string& script_path) const {
  const CommandResult r = runCommand({"sbatch", "--parsable", script_path});
  const std::string job = trim(r.out.substr(0, r.out.find(';')));
  if (r.exit_code != 0 || job.empty() || job.find_first_not_of("0123456789") != std::string::npos) {
    throw InputError(script_path, 0,
                     "Slurm rejected the job array (sbatch exit code " +
                         std::to_string(r.exit_code) + "): " + trim(r.err + "\n" + r.out));
  }
  return job;
}

TaskStates SlurmClient::taskStates(const std::set<std::string>& job_ids, bool* query_failed) const {
  TaskStates states;
  for (const std::string& job : job_ids) {
    const CommandResult q =
        runCommand({"squeue", "-h", "-r", "-t", "all", "-j", job, "-o", "%i|%T"});
    if (q.exit_code == 0) {
      parseStates(q.out, &states);
      continue;
    }
    // A purged job: "Invalid job id specified". Anything else is the controller's problem.
    if (q.err.find("Invalid job id") == std::string::npos) *query_failed = true;
    // Accounting knows what squeue has forgotten; without a slurmdbd sacct fails, which is fine.
    const CommandResult a = runCommand({"sacct", "-n", "-P", "-X", "-j", job, "-o", "JobID,State"});
    if (a.exit_code == 0) parseStates(a.out, &states);
  }
  return states;
}

bool SlurmClient::cancel(const std::vector<std::string>& ids, std::string* message) const {
  std::vector<std::string> argv = {"scancel"};
  argv.insert(argv.end(), ids.begin(), ids.end());
  const CommandResult r = runCommand(argv);
  if (message != nullptr) *message = trim(r.err + r.out);
  return r.exit_code == 0;
}

bool SlurmClient::available(std::string* why) {
  const CommandResult r = runCommand({"sinfo", "-h", "-o", "%T"});
  if (r.exit_code == 0 && !trim(r.out).empty()) return true;
  if (why != nullptr) {
    *why = r.exit_code == 0 ? "sinfo lists no node" : "sinfo failed: " + trim(r.err + r.out);
  }
  return false;
}

bool isPendingState(const std::string& state) {
  return state == "PENDING" || state == "REQUEUED" || state == "REQUEUE_HOLD" ||
         state == "REQUEUE_FED" || state == "RESV_DEL_HOLD" || state == "SPECIAL_EXIT";
}

bool isActiveState(const std::string& state) {
  return isPendingState(state) || state == "RUNNING" || state == "CONFIGURING" ||
         state == "COMPLETING" || state == "SUSPENDED" || state == "STOPPED" ||
         state == "SIGNALING" || state == "STAGE_OUT" || state == "RESIZING";
}

}  // namespace marglab::experiment
