#pragma once
// SIGINT / SIGTERM / SIGHUP while output files are being written (docs/design.md §7); SIGXFSZ is
// ignored so that a write beyond the file size limit fails with EFBIG and is cleaned up. The
// handler is installed for a signal whose action is still the default, as soon as the first
// temporary exists (AtomicFile), and acts in one of two ways; either way the process exits with 128 + the signal
// number (130 for SIGINT, 143 for SIGTERM) and leaves no "*.tmp-*" file:
//   - by default it unlinks the live temporaries (atomic_file.h) and calls _exit (both
//     async-signal-safe);
//   - inside an InterruptPolling scope (a loop that calls throwIfInterrupted() often, such as the
//     frame loop of `marglab run`) it only records the signal; throwIfInterrupted() then throws
//     Interrupted, the stack unwinds (the writers' destructors remove their temporaries) and the
//     verb returns Interrupted::exitCode().
// A signal that is ignored (nohup) or handled by someone else (the sweep runner) is left alone.

#include <stdexcept>

namespace marglab {

class Interrupted : public std::runtime_error {
 public:
  explicit Interrupted(int signal);
  int signal() const { return signal_; }
  int exitCode() const { return 128 + signal_; }

 private:
  int signal_;
};

// Idempotent; called by AtomicFile and InterruptPolling.
void installInterruptCleanup();

// The signal recorded in a polling scope, 0 when none.
int interruptSignal();
void throwIfInterrupted();

class InterruptPolling {
 public:
  InterruptPolling();
  ~InterruptPolling();
  InterruptPolling(const InterruptPolling&) = delete;
  InterruptPolling& operator=(const InterruptPolling&) = delete;
};

}  // namespace marglab
