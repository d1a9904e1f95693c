// core/common/subprocess.h: a helper never outlives the marglab process that started it (issue
// #32, defect 2). A "parent" is forked from the test and runs a helper script through runChild;
// the test stops or kills the parent and then asks pgrep whether anything the helper started is
// still running — the helper itself, a member of its process group that ignores SIGTERM, and a
// process in a session of its own (as Jupyter starts its kernels) that ignores SIGTERM too.

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/common/subprocess.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;

class Subprocess : public test::TempDirTest {
 protected:
  void SetUp() override {
    // A sleep whose command line no other process on the machine has: what pgrep looks for
    // (60 s: what a failing test leaves behind ends by itself).
    marker_ = "60." + std::to_string(getpid());
  }

  // Forks a parent that runs `script` through runChild and exits with the helper's exit code,
  // or 128 + the stop signal that ended it.
  pid_t startParent(const std::string& script) const {
    const pid_t pid = fork();
    if (pid == 0) {
      ChildSpec spec;
      spec.argv = {"sh", "-c", script};
      const ChildResult result = runChild(spec);
      _exit(result.stop_signal != 0 ? exitCodeForSignal(result.stop_signal) : result.exit_code);
    }
    return pid;
  }

  // pgrep's pattern for the marker; "[6]0" so that it does not match the shell running pgrep.
  std::string pattern() const { return "'[6]0[.]" + marker_.substr(3) + "'"; }
  bool anyRunning() const { return test::runShell("pgrep -f " + pattern()).exit_code == 0; }

  static bool waitForFile(const fs::path& path) {
    for (int i = 0; i < 3000 && !fs::exists(path); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return fs::exists(path);
  }

  // The helper: a group member and a process in its own session, both deaf to SIGTERM, then
  // "ready", then `tail` (by default a long sleep).
  std::string helperScript(const std::string& tail = "") const {
    const std::string deaf = "trap '' TERM; sleep " + marker_ + "; :";
    return "sh -c \"" + deaf + "\" & setsid sh -c \"" + deaf + "\" & sleep 0.2; touch '" +
           (dir_ / "ready").string() + "'; " + (tail.empty() ? "sleep " + marker_ + "; :" : tail);
  }

  std::string marker_;
};

int exitCodeOfWait(pid_t pid) {
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return -1;
  return exitCodeOf(status);
}

TEST_F(Subprocess, StoppedParentStopsTheHelperAndEverythingItStarted) {
  for (const int signal : {SIGTERM, SIGINT}) {
    SCOPED_TRACE(signal);
    fs::remove(dir_ / "ready");
    const pid_t parent = startParent(helperScript());
    ASSERT_GT(parent, 0);
    ASSERT_TRUE(waitForFile(dir_ / "ready"));
    ASSERT_TRUE(anyRunning());
    ASSERT_EQ(kill(parent, signal), 0);
    EXPECT_EQ(exitCodeOfWait(parent), 128 + signal);
    // Once the parent has exited nothing of the helper runs, so nothing can write any more.
    EXPECT_FALSE(anyRunning()) << test::runShell("pgrep -af " + pattern()).output;
  }
}

TEST_F(Subprocess, HelperEndingNormallyLeavesNothingBehind) {
  const pid_t parent = startParent(helperScript("exit 3"));
  ASSERT_GT(parent, 0);
  EXPECT_EQ(exitCodeOfWait(parent), 3);
  EXPECT_FALSE(anyRunning()) << test::runShell("pgrep -af " + pattern()).output;
}

TEST_F(Subprocess, HelperDiesWithASigkilledParent) {
  // The pid file appears by rename, whole: a file that the shell's redirection had created but
  // not yet written, read as "" after the kernel killed the helper, made the path /proc//cmdline,
  // i.e. /proc/cmdline, which never empties.
  const fs::path pid_file = dir_ / "pid";
  const pid_t parent =
      startParent("echo $$ > '" + pid_file.string() + ".tmp'; mv '" + pid_file.string() +
                  ".tmp' '" + pid_file.string() + "'; sleep " + marker_ + "; :");
  ASSERT_GT(parent, 0);
  ASSERT_TRUE(waitForFile(pid_file));
  ASSERT_EQ(kill(parent, SIGKILL), 0);
  EXPECT_EQ(exitCodeOfWait(parent), 128 + SIGKILL);
  std::string pid_text;
  std::ifstream(pid_file) >> pid_text;
  ASSERT_FALSE(pid_text.empty());
  ASSERT_EQ(pid_text.find_first_not_of("0123456789"), std::string::npos) << pid_text;
  const std::string proc = "/proc/" + pid_text + "/cmdline";
  // PR_SET_PDEATHSIG: the kernel kills the helper as its parent dies (a zombie until reaped by
  // init has an empty command line).
  bool gone = false;
  for (int i = 0; i < 3000 && !gone; ++i) {
    gone = test::readText(proc).empty();
    if (!gone) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_TRUE(gone) << "the helper outlived its SIGKILLed parent";
  // The helper's own sleep outlives it (nothing is left to end it): end it here, so that a
  // repeated run of these tests does not find it.
  test::runShell("pkill -f " + pattern());
}

TEST_F(Subprocess, ExitCodesFollowTheShellConvention) {
  ChildSpec spec;
  spec.discard_output = true;
  spec.argv = {"sh", "-c", "exit 3"};
  EXPECT_EQ(runChild(spec).exit_code, 3);
  spec.argv = {"sh", "-c", "kill -TERM $$"};
  EXPECT_EQ(runChild(spec).exit_code, 128 + SIGTERM);
  spec.argv = {"marglab-no-such-program"};
  EXPECT_EQ(runChild(spec).exit_code, 127);
  EXPECT_FALSE(probeSucceeds({"marglab-no-such-program"}));
  EXPECT_TRUE(probeSucceeds({"true"}));
}

// The log path is the parent's (relative to its working directory), the working directory the
// child's: the sweep's tracking child of issue #32 defect 1 wrote its log relative to the wrong one.
TEST_F(Subprocess, OutputPathIsTheParentsAndWorkingDirectoryTheChilds) {
  fs::create_directories(dir_ / "work");
  ChildSpec spec;
  spec.argv = {"sh", "-c", "pwd; echo to-stderr >&2"};
  spec.working_dir = (dir_ / "work").string();
  spec.output = (dir_ / "log.txt").string();
  EXPECT_EQ(runChild(spec).exit_code, 0);
  const std::string log = test::readText(dir_ / "log.txt");
  EXPECT_NE(log.find(fs::canonical(dir_ / "work").string() + "\n"), std::string::npos) << log;
  EXPECT_NE(log.find("to-stderr"), std::string::npos) << log;
  spec.output = (dir_ / "no-such-folder" / "log.txt").string();
  try {
    runChild(spec);
    ADD_FAILURE() << "a log in a missing folder was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(spec.output), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace marglab
