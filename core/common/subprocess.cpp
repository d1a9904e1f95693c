#include "core/common/subprocess.h"

#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <set>
#include <sstream>

#include "core/common/error.h"
#include "core/common/interrupt.h"

extern char** environ;

namespace marglab {
namespace {

volatile std::sig_atomic_t g_stop_signal = 0;
std::atomic<int> g_scopes{0};

extern "C" void onStopSignal(int signal) { g_stop_signal = signal; }

// argv[0] as exec will find it: a name without '/' is looked up on PATH here, in the parent,
// because the child of a multi-threaded process may only make async-signal-safe calls.
std::string resolveProgram(const std::string& name) {
  if (name.find('/') != std::string::npos) return name;
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path != nullptr ? path : "/usr/local/bin:/usr/bin:/bin");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const std::string candidate = (dir.empty() ? "." : dir) + "/" + name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return name;  // exec fails with ENOENT: the child says so and exits 127
}

int openOutput(const ChildSpec& spec) {
  if (!spec.discard_output && spec.output.empty()) return -1;
  const std::string path = spec.discard_output ? "/dev/null" : spec.output;
  const int fd = ::open(path.c_str(), O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    throw InputError(
        path, 0,
        std::string("cannot open the log of ") + spec.argv.front() + ": " + std::strerror(errno));
  }
  return fd;
}

void writeStderr(const char* text) {
  [[maybe_unused]] const ssize_t n = ::write(STDERR_FILENO, text, std::strlen(text));
}

// In the child: only async-signal-safe calls.
[[noreturn]] void execChild(pid_t parent, int out_fd, int null_fd, const char* dir,
                            const char* program, char* const* argv) {
  ::setpgid(0, 0);
  if (::prctl(PR_SET_PDEATHSIG, SIGKILL) != 0 || ::getppid() != parent) ::_exit(126);
  ::signal(SIGINT, SIG_DFL);
  ::signal(SIGTERM, SIG_DFL);
  if (null_fd < 0) ::_exit(126);
  ::dup2(null_fd, STDIN_FILENO);
  if (out_fd >= 0) {
    ::dup2(out_fd, STDOUT_FILENO);
    ::dup2(out_fd, STDERR_FILENO);
  }
  if (dir != nullptr && ::chdir(dir) != 0) {
    writeStderr("marglab: cannot enter the working directory of a helper process\n");
    ::_exit(126);
  }
  ::execv(program, argv);
  writeStderr("marglab: cannot execute ");
  writeStderr(program);
  writeStderr("\n");
  ::_exit(127);
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

void sleepBriefly() {
  const timespec pause{0, 10'000'000};  // 10 ms: a stop signal is forwarded within it
  ::nanosleep(&pause, nullptr);
}

}  // namespace

pid_t startChild(const ChildSpec& spec) {
  if (spec.argv.empty()) throw InputError("", 0, "startChild: no program");
  const std::string program = resolveProgram(spec.argv.front());
  std::vector<std::string> args = spec.argv;
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const int out_fd = openOutput(spec);
  const int null_fd = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  const char* dir = spec.working_dir.empty() ? nullptr : spec.working_dir.c_str();
  std::fflush(nullptr);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) execChild(parent, out_fd, null_fd, dir, program.c_str(), argv.data());
  const int fork_error = errno;
  if (out_fd >= 0) ::close(out_fd);
  if (null_fd >= 0) ::close(null_fd);
  if (pid < 0) {
    throw InputError(
        "", 0, "cannot start " + spec.argv.front() + ": fork failed: " + std::strerror(fork_error));
  }
  // Also in the parent, so that a signal sent to the group right after fork cannot miss the child.
  ::setpgid(pid, pid);
  return pid;
}

void signalChildGroup(pid_t child, int signal) {
  if (child > 0) ::killpg(child, signal);
}

int exitCodeOf(int wait_status) {
  if (WIFSIGNALED(wait_status)) return exitCodeForSignal(WTERMSIG(wait_status));
  return WIFEXITED(wait_status) ? WEXITSTATUS(wait_status) : 1;
}

namespace {

// Our children, from /proc (field 4 of /proc/PID/stat is the parent's pid).
std::set<pid_t> childrenOfThisProcess() {
  std::set<pid_t> children;
  const pid_t self = ::getpid();
  DIR* proc = ::opendir("/proc");
  if (proc == nullptr) return children;
  while (const dirent* entry = ::readdir(proc)) {
    char* end = nullptr;
    const long pid = std::strtol(entry->d_name, &end, 10);
    if (pid <= 0 || *end != '\0') continue;
    std::ifstream stat(std::string("/proc/") + entry->d_name + "/stat");
    std::string line;
    std::getline(stat, line);
    const auto close = line.rfind(')');  // the command name may hold spaces and parentheses
    if (close == std::string::npos) continue;
    std::istringstream fields(line.substr(close + 1));
    char state = 0;
    long ppid = 0;
    if (fields >> state >> ppid && ppid == self) children.insert(static_cast<pid_t>(pid));
  }
  ::closedir(proc);
  return children;
}

// Kills and reaps every child that was not there before: the helper's descendants, which were
// reparented to us (the subreaper) when their parents died — e.g. Jupyter kernels, which run in
// sessions of their own where the killpg of the helper's group does not reach them.
void endOrphans(const std::set<pid_t>& before) {
  for (;;) {
    std::vector<pid_t> orphans;
    for (const pid_t pid : childrenOfThisProcess()) {
      if (!before.count(pid)) orphans.push_back(pid);
    }
    if (orphans.empty()) return;
    for (const pid_t pid : orphans) ::kill(pid, SIGKILL);
    for (const pid_t pid : orphans) {
      while (::waitpid(pid, nullptr, 0) < 0 && errno == EINTR) {
      }
    }
  }
}

// Waits for the child to end without reaping it, forwarding stop signals to its group; returns
// the signal forwarded last (0: none).
int awaitEnd(pid_t pid) {
  int forwarded = 0;
  while (true) {
    if (const int signal = StopSignals::received(); signal != 0 && signal != forwarded) {
      signalChildGroup(pid, signal);
      forwarded = signal;
    }
    siginfo_t info{};
    // WNOWAIT: the child stays a zombie, so its group id is not reused before the killpg below.
    const int r = ::waitid(P_PID, static_cast<id_t>(pid), &info, WEXITED | WNOHANG | WNOWAIT);
    if ((r == 0 && info.si_pid == pid) || (r != 0 && errno != EINTR)) return forwarded;
    sleepBriefly();
  }
}

}  // namespace

ChildResult runChild(const ChildSpec& spec) {
  const StopSignals stop;
  // As the subreaper, this process inherits the helper's orphans and so can end them all.
  int was_subreaper = 0;
  ::prctl(PR_GET_CHILD_SUBREAPER, &was_subreaper);
  ::prctl(PR_SET_CHILD_SUBREAPER, 1);
  const std::set<pid_t> before = childrenOfThisProcess();
  ChildResult result;
  try {
    const pid_t pid = startChild(spec);
    result.stop_signal = awaitEnd(pid);
    signalChildGroup(pid, SIGKILL);  // whatever the helper left running in its group
    int status = 0;
    while (::wait4(pid, &status, 0, &result.usage) < 0 && errno == EINTR) {
    }
    result.exit_code = exitCodeOf(status);
    endOrphans(before);
  } catch (...) {
    ::prctl(PR_SET_CHILD_SUBREAPER, was_subreaper);
    throw;
  }
  ::prctl(PR_SET_CHILD_SUBREAPER, was_subreaper);
  return result;
}

int runHelper(const std::vector<std::string>& argv) {
  ChildSpec spec;
  spec.argv = argv;
  const ChildResult result = runChild(spec);
  if (result.stop_signal != 0) throw Interrupted(result.stop_signal);
  return result.exit_code;
}

bool probeSucceeds(const std::vector<std::string>& argv) {
  ChildSpec spec;
  spec.argv = argv;
  spec.discard_output = true;
  const ChildResult result = runChild(spec);
  if (result.stop_signal != 0) throw Interrupted(result.stop_signal);
  return result.exit_code == 0;
}

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

StopSignals::StopSignals() {
  if (g_scopes++ > 0) return;
  g_stop_signal = 0;
  struct sigaction action {};
  action.sa_handler = onStopSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, &old_int_);
  sigaction(SIGTERM, &action, &old_term_);
}

StopSignals::~StopSignals() {
  if (--g_scopes > 0) return;
  sigaction(SIGINT, &old_int_, nullptr);
  sigaction(SIGTERM, &old_term_, nullptr);
}

int StopSignals::received() { return g_stop_signal; }

}  // namespace marglab
