#include "core/io/hdf5_trust.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <new>

#include <fmt/format.h>

#include "core/common/error.h"

namespace marglab::h5 {
namespace {

// How the child ends besides 0 (the read returned); its pipe carries the details.
constexpr int kInputError = 1;  // pipe: file, line, detail, separated by '\0'
constexpr int kOutOfMemory = 2;
constexpr int kException = 3;  // pipe: what()

// Bytes mapped by this process (VmSize, what RLIMIT_AS compares with); 0 if unknown.
std::uint64_t mappedBytes() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmSize:", 0) == 0) return std::stoull(line.substr(7)) * 1024;
  }
  return 0;
}

void writeAll(int fd, const std::string& s) {
  for (std::size_t done = 0; done < s.size();) {
    const ssize_t n = ::write(fd, s.data() + done, s.size() - done);
    if (n < 0 && errno != EINTR) return;
    if (n > 0) done += static_cast<std::size_t>(n);
  }
}

[[noreturn]] void runInChild(pid_t parent, int out, const std::function<void()>& read,
                             const ReadLimits& limits) {
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (::getppid() != parent) ::_exit(kException);  // the parent died before prctl
  std::signal(SIGINT, SIG_IGN);
  std::signal(SIGTERM, SIG_IGN);
  // Without /proc the budget cannot be placed above what is mapped: no address-space limit then.
  if (const std::uint64_t mapped = mappedBytes(); mapped > 0) {
    const rlimit address{mapped + limits.address_space_bytes, mapped + limits.address_space_bytes};
    setrlimit(RLIMIT_AS, &address);
  }
  // SIGXCPU at the soft limit; the hard one, a second later, is SIGKILL.
  const rlimit cpu{static_cast<rlim_t>(limits.cpu_seconds),
                   static_cast<rlim_t>(limits.cpu_seconds) + 1};
  setrlimit(RLIMIT_CPU, &cpu);
  int code = 0;
  std::string details;
  try {
    read();
  } catch (const InputError& e) {
    code = kInputError;
    details = e.file() + '\0' + std::to_string(e.line()) + '\0' + e.detail();
  } catch (const std::bad_alloc&) {
    code = kOutOfMemory;
  } catch (const std::exception& e) {
    code = kException;
    details = e.what();
  }
  writeAll(out, details);
  ::_exit(code);  // no destructors, atexit handlers or stdio flushes of the parent's state
}

struct ChildEnd {
  int status = 0;
  bool timed_out = false;
  std::string details;
};

// Reads the child's pipe to its end and reaps the child; SIGKILLs it at the deadline.
ChildEnd awaitChild(pid_t pid, int in, int wall_seconds) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point deadline = Clock::now() + std::chrono::seconds(wall_seconds);
  ChildEnd end;
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) {
      end.timed_out = true;
      ::kill(pid, SIGKILL);
      break;
    }
    pollfd p{in, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left)) <= 0) continue;  // EINTR or the deadline: re-check
    char buffer[4096];
    const ssize_t n = ::read(in, buffer, sizeof buffer);
    if (n > 0) end.details.append(buffer, static_cast<std::size_t>(n));
    if (n == 0 || (n < 0 && errno != EINTR)) break;  // the child has closed it: it is ending
  }
  ::close(in);
  while (::waitpid(pid, &end.status, 0) < 0 && errno == EINTR) {
  }
  return end;
}

std::string bytesText(std::uint64_t bytes) {
  return bytes >= (std::uint64_t{1} << 30) ? fmt::format("{} GiB", bytes >> 30)
                                           : fmt::format("{} MiB", bytes >> 20);
}

// The child's InputError (file, line and detail, separated by '\0') as it threw it.
[[noreturn]] void rethrowInputError(const std::string& path, const std::string& details) {
  const std::size_t a = details.find('\0');
  const std::size_t b = a == std::string::npos ? a : details.find('\0', a + 1);
  if (b == std::string::npos) throw InputError(path, 0, "reading it failed: " + details);
  throw InputError(details.substr(0, a), std::atoi(details.substr(a + 1, b - a - 1).c_str()),
                   details.substr(b + 1));
}

// Throws the InputError for a child that did not end normally.
void throwUnlessClean(const std::string& path, const ChildEnd& end, const ReadLimits& limits) {
  constexpr const char* kStopped =
      "its reader was stopped: libhdf5 can loop forever on a corrupted file";
  if (end.timed_out) {
    throw InputError(
        path, 0, fmt::format("reading it took more than {} s ({})", limits.wall_seconds, kStopped));
  }
  if (WIFSIGNALED(end.status)) {
    const int signal = WTERMSIG(end.status);
    if (signal == SIGXCPU) {
      throw InputError(path, 0,
                       fmt::format("reading it took more than {} s of CPU time ({})",
                                   limits.cpu_seconds, kStopped));
    }
    throw InputError(path, 0,
                     fmt::format("reading it crashed (signal {}, {}): libhdf5 does not survive "
                                 "every corrupted file",
                                 signal, strsignal(signal)));
  }
  const int code = WEXITSTATUS(end.status);
  if (code == kInputError) rethrowInputError(path, end.details);
  if (code == kOutOfMemory) {
    throw InputError(path, 0,
                     "reading it needed more than " + bytesText(limits.address_space_bytes) +
                         " of memory: the file claims sizes it does not hold");
  }
  if (code == kException) throw InputError(path, 0, "reading it failed: " + end.details);
  if (code != 0) throw InputError(path, 0, fmt::format("its reader exited with code {}", code));
}

}  // namespace

void checkReadableInChild(const std::string& path, const std::function<void()>& read,
                          const ReadLimits& limits) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    throw InputError(path, 0,
                     std::string("cannot read it in a child: pipe: ") + std::strerror(errno));
  }
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    runInChild(parent, fds[1], read, limits);
  }
  const int fork_error = errno;
  ::close(fds[1]);
  if (pid < 0) {
    ::close(fds[0]);
    throw InputError(path, 0,
                     std::string("cannot read it in a child: fork: ") + std::strerror(fork_error));
  }
  throwUnlessClean(path, awaitChild(pid, fds[0], limits.wall_seconds), limits);
}

}  // namespace marglab::h5
