#include "core/common/interrupt.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstring>
#include <mutex>
#include <string>

#include "core/common/atomic_file.h"

namespace marglab {
namespace {

volatile std::sig_atomic_t g_signal = 0;
std::atomic<int> g_polling{0};
static_assert(std::atomic<int>::is_always_lock_free, "read by the signal handler");

extern "C" void onInterrupt(int signal) {
  g_signal = signal;
  if (g_polling.load() > 0) return;
  detail::unlinkLiveTemporaries();
  // write(2) only: the one async-signal-safe way to say why the process stops.
  const char* text =
      signal == SIGINT ? "\nmarglab: interrupted by SIGINT: stopped, unfinished outputs removed\n"
      : signal == SIGHUP
          ? "\nmarglab: interrupted by SIGHUP: stopped, unfinished outputs removed\n"
          : "\nmarglab: interrupted by SIGTERM: stopped, unfinished outputs removed\n";
  [[maybe_unused]] const ssize_t n = ::write(STDERR_FILENO, text, std::strlen(text));
  ::_exit(128 + signal);
}

void installIfDefault(int signal) {
  struct sigaction current {};
  if (sigaction(signal, nullptr, &current) != 0 || current.sa_handler != SIG_DFL) return;
  struct sigaction action {};
  action.sa_handler = onInterrupt;
  sigemptyset(&action.sa_mask);
  sigaction(signal, &action, nullptr);
}

std::string signalName(int signal) {
  const char* abbrev = sigabbrev_np(signal);
  return abbrev != nullptr ? std::string("SIG") + abbrev : "signal " + std::to_string(signal);
}

}  // namespace

Interrupted::Interrupted(int signal)
    : std::runtime_error("interrupted by " + signalName(signal)), signal_(signal) {}

void installInterruptCleanup() {
  static std::once_flag once;
  std::call_once(once, [] {
    installIfDefault(SIGINT);
    installIfDefault(SIGTERM);
    installIfDefault(SIGHUP);  // the terminal closed
    // Beyond the file size limit (ulimit -f), write(2) then fails with EFBIG, which the writer
    // reports and cleans up after, instead of the default SIGXFSZ killing the process mid-write.
    struct sigaction current {};
    if (sigaction(SIGXFSZ, nullptr, &current) == 0 && current.sa_handler == SIG_DFL) {
      std::signal(SIGXFSZ, SIG_IGN);
    }
  });
}

int interruptSignal() { return g_signal; }

void throwIfInterrupted() {
  if (const int signal = g_signal) throw Interrupted(signal);
}

InterruptPolling::InterruptPolling() {
  installInterruptCleanup();
  ++g_polling;
}

InterruptPolling::~InterruptPolling() { --g_polling; }

}  // namespace marglab
