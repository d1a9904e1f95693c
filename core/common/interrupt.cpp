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
