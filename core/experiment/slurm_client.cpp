#include "core/experiment/slurm_client.h"

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>
#include <array>
#include <cerrno>
#include <sstream>

#include "core/common/error.h"

extern char** environ;

namespace marglab::experiment {
namespace {

std::string trim(const std::string& text) {
  const auto a = text.find_first_not_of(" \t\r\n");
  const auto b = text.find_last_not_of(" \t\r\n");
  return a == std::string::npos ? "" : text.substr(a, b - a + 1);
}

// Reads both pipes to their end together, so that neither fills up and blocks the child.
void drain(int out_fd, int err_fd, CommandResult* result) {
  std::array<pollfd, 2> fds{pollfd{out_fd, POLLIN, 0}, pollfd{err_fd, POLLIN, 0}};
  std::array<std::string*, 2> sinks{&result->out, &result->err};
  int open_fds = 2;
  char buffer[4096];
  while (open_fds > 0) {
    if (poll(fds.data(), fds.size(), -1) < 0 && errno != EINTR) break;
    for (std::size_t i = 0; i < fds.size(); ++i) {
      if (fds[i].fd < 0 || fds[i].revents == 0) continue;
      const ssize_t n = read(fds[i].fd, buffer, sizeof(buffer));
      if (n > 0) {
        sinks[i]->append(buffer, static_cast<std::size_t>(n));
      } else if (n == 0 || errno != EINTR) {
        close(fds[i].fd);
        fds[i].fd = -1;
        --open_fds;
      }
    }
  }
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

CommandResult runCommand(const std::vector<std::string>& argv) {
  CommandResult result;
  int out_pipe[2], err_pipe[2];
  if (pipe2(out_pipe, O_CLOEXEC) != 0) return result;
  if (pipe2(err_pipe, O_CLOEXEC) != 0) {
    close(out_pipe[0]);
    close(out_pipe[1]);
    return result;
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, out_pipe[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, err_pipe[1], STDERR_FILENO);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(out_pipe[1]);
  close(err_pipe[1]);
  if (rc != 0) {
    close(out_pipe[0]);
    close(err_pipe[0]);
    result.err = argv[0] + ": cannot run it (not installed, or not on PATH)";
    return result;
  }
  drain(out_pipe[0], err_pipe[0], &result);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return result;
}

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
