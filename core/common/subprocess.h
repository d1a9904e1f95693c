#pragma once
// The one home of marglab's process plumbing: every helper process (a sweep's runs and its
// `datasets track` children, the notebook runner, the report's scripts and headless Chromium, the
// bench's whole runs, the Python probes) is started and waited for here, so that a helper never
// outlives the marglab process that started it and never writes into a folder after that process
// released it (its sweep lock, its output folder). The one process started elsewhere runs no
// program: the child that reads a user's HDF5 file first (core/io/hdf5_trust.h), bounded by its
// own limits and ended with the thread that forked it.
//
// Contract of a child started by startChild:
//   - it leads its own process group (setpgid), so that one killpg reaches everything it started
//     in that group (Jupyter's nbclient, Chromium and its renderers, `sh -c` pipelines);
//   - it dies with its parent: PR_SET_PDEATHSIG SIGKILL (also when the parent is SIGKILLed), and a
//     parent that died before prctl is caught by getppid();
//   - SIGINT and SIGTERM are at their default actions in it, stdin is /dev/null, and stdout +
//     stderr go where the spec says (inherited, appended to a file, or /dev/null);
//   - no std::system: the parent never ignores SIGINT / SIGQUIT while it waits (std::system does,
//     which is how a Ctrl-C used to reach only the child and the parent carried on).
//
// runChild waits for the child inside a StopSignals scope: a SIGINT / SIGTERM sent to marglab is
// forwarded to the child's group; once the child has ended, the rest of its group is SIGKILLed,
// and so is every descendant it left behind in other sessions (Jupyter starts its kernels with
// setsid): marglab is their subreaper (PR_SET_CHILD_SUBREAPER) while it waits, inherits them
// when their parents die, and kills and reaps them before runChild returns. So when runChild
// returns, nothing the helper started is running. The caller then stops with exitCodeForSignal(result.stop_signal), the
// shell's 128 + signal convention used everywhere (core/common/interrupt.h).

#include <signal.h>
#include <sys/resource.h>
#include <sys/types.h>

#include <string>
#include <vector>

namespace marglab {

struct ChildSpec {
  std::vector<std::string> argv;  // argv[0]: a path, or a name looked up on PATH
  std::string working_dir;        // "" = the parent's
  std::string output;             // stdout + stderr appended to this file (relative to the
                                  // parent's working directory); "" = inherited
  bool discard_output = false;    // stdout + stderr to /dev/null (overrides output)
};

// Starts the child (contract above). Throws InputError naming the program when fork fails; an
// exec that fails ends the child with exit code 127 and a line on its stderr.
pid_t startChild(const ChildSpec& spec);

// Sends `signal` to the child's process group (startChild made the child its leader).
void signalChildGroup(pid_t child, int signal);

// The exit code a shell reports for a wait status: the exit status, or 128 + the signal.
int exitCodeOf(int wait_status);
inline int exitCodeForSignal(int signal) { return 128 + signal; }

struct ChildResult {
  int exit_code = 0;    // exitCodeOf(wait status)
  int stop_signal = 0;  // SIGINT / SIGTERM that reached the parent while it waited; 0 if none
  rusage usage{};       // of the child (wait4)
};

// startChild + wait, forwarding SIGINT / SIGTERM to the child's group; what the child left running
// is killed and reaped before it returns (above). Call it while this process starts no children
// of its own on other threads: every new child is taken for one of the helper's orphans.
ChildResult runChild(const ChildSpec& spec);

// runChild with the output inherited (a script that reports to the user): the exit code; throws
// Interrupted (interrupt.h: the verb exits 128 + signal) when a stop signal ended it.
int runHelper(const std::vector<std::string>& argv);

// Whether the program exits 0, its output discarded (probes: a Python that has the modules, a
// browser on PATH). Throws Interrupted like runHelper.
bool probeSucceeds(const std::vector<std::string>& argv);

// A short command whose output is wanted (the Slurm client's sbatch, squeue, scancel): argv[0]
// searched on PATH, stdin /dev/null, stdout and stderr read to their end together (neither pipe
// fills up and blocks the child). It stays in this process's group: a Ctrl-C reaches it too.
struct CommandResult {
  int exit_code = -1;  // -1: could not start, 128+N: killed by signal N
  std::string out;     // stdout
  std::string err;     // stderr
};
CommandResult runCommand(const std::vector<std::string>& argv);

// While an object lives, SIGINT and SIGTERM are recorded instead of acting (the previous actions
// are restored by the destructor): the sweep's loop, a Slurm follower and runChild poll
// stopSignal() and wind down in order. Nestable: an inner scope keeps a signal the outer one
// recorded, and the outer one sees a signal recorded inside.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

  // The last SIGINT / SIGTERM recorded by any live scope since the outermost one began; 0 if none.
  static int received();

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

}  // namespace marglab
