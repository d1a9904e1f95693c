// A sweep folder belongs to one sweep at a time (issue 18 item 3): a second sweep on a locked
// folder exits 1 naming the owner's pid and host; the runs of a SIGKILLed sweep die with it
// (PR_SET_PDEATHSIG), its lock is taken over, and --resume redoes the interrupted run once; a run
// that fills its disk is recorded as an error with the reason, not as a signal (item 1).

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "common/cli_runner.h"
#include "common/fault_injection.h"
#include "common/temp_dir.h"
#include "core/common/error.h"
#include "core/experiment/sweep_common.h"
#include "core/experiment/sweep_index.h"

namespace marglab::experiment {
namespace {

namespace fs = std::filesystem;
using test::readText;
using test::runCli;
using test::startCli;

class SweepLockTest : public test::TempDirTest {
 protected:
  std::string q(const fs::path& p) const { return "'" + p.string() + "'"; }
  // One run of KITTI 10 reading its tracks from `tracks` (a FIFO blocks it until written).
  fs::path writeSweep(const fs::path& tracks) const {
    const fs::path file = dir_ / "lock.toml";
    std::ofstream(file) << "name = \"lock\"\n[[group]]\nname = \"g\"\n"
                        << "datasets = [\"kitti/10\"]\nvariants = [\"ns-qr-sqrt-f64\"]\n"
                        << "frames = 10\nargs = [\"--tracks\", \"" << tracks.string() << "\"]\n";
    return file;
  }
};

std::string hostName() {
  char host[256] = {};
  gethostname(host, sizeof(host) - 1);
  return host;
}

// A process that is gone or a zombie (a container's init may not reap orphans).
bool processGone(pid_t pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  if (!stat) return true;
  std::string text((std::istreambuf_iterator<char>(stat)), std::istreambuf_iterator<char>());
  const auto paren = text.rfind(')');
  return paren != std::string::npos && paren + 2 < text.size() && text[paren + 2] == 'Z';
}

// Bounded waits for an event (so that a broken build fails instead of hanging).
template <typename F>
bool waitFor(F&& done) {
  for (int i = 0; i < 3000; ++i) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

TEST_F(SweepLockTest, LockNamesItsOwnerAndIsReleasedWithIt) {
  const fs::path out = dir_ / "out";
  {
    const detail::SweepLock lock(out);
    try {
      const detail::SweepLock second(out);
      ADD_FAILURE() << "a second lock was granted";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_EQ(e.file(), (out / ".lock").string());
      EXPECT_NE(what.find("in use by another marglab sweep (pid " + std::to_string(::getpid()) +
                          " host " + hostName() + " since "),
                std::string::npos)
          << what;
    }
  }
  EXPECT_NO_THROW(detail::SweepLock again(out));
}

TEST_F(SweepLockTest, SecondSweepRefusedAndAKilledSweepTakesItsRunAlong) {
  const fs::path tracks = dir_ / "tracks.txt";
  ASSERT_EQ(mkfifo(tracks.c_str(), 0644), 0);
  const fs::path sweep_file = writeSweep(tracks);
  const fs::path out = dir_ / "out";
  const pid_t sweep = startCli({"sweep", sweep_file.string(), "--jobs", "1", "--out", out.string()},
                               (dir_ / "sweep.log").string());
  ASSERT_GT(sweep, 0);
  pid_t child = 0;
  ASSERT_TRUE(waitFor([&] {
    try {
      const auto rows = readIndex((out / "index.csv").string());
      if (rows.size() == 1 && rows[0].get("status") == "running" && !rows[0].get("pid").empty()) {
        child = static_cast<pid_t>(std::stol(rows[0].get("pid")));
      }
    } catch (const std::exception&) {
      // no index yet
    }
    return child != 0;
  })) << readText(dir_ / "sweep.log");
  // The run is blocked opening the FIFO: it is certainly still running.
  EXPECT_FALSE(processGone(child));

  for (const char* mode : {"--force", "--resume"}) {
    const auto second = runCli("sweep " + q(sweep_file) + " " + mode + " --out " + q(out));
    EXPECT_EQ(second.exit_code, 1) << second.output;
    EXPECT_NE(second.output.find("in use by another marglab sweep (pid " + std::to_string(sweep) +
                                 " host " + hostName()),
              std::string::npos)
        << second.output;
  }
  EXPECT_EQ(readIndex((out / "index.csv").string())[0].get("status"), "running");

  ASSERT_EQ(kill(sweep, SIGKILL), 0);
  ASSERT_EQ(waitpid(sweep, nullptr, 0), sweep);
  EXPECT_TRUE(waitFor([&] { return processGone(child); })) << "the run outlived its sweep";

  fs::remove(tracks);
  const auto simulate = runCli("datasets simulate --dataset kitti/10 --frames 10 -o " + q(tracks));
  ASSERT_EQ(simulate.exit_code, 0) << simulate.output;
  const auto resume = runCli("sweep " + q(sweep_file) + " --resume --out " + q(out));
  ASSERT_EQ(resume.exit_code, 0) << resume.output;
  EXPECT_NE(resume.output.find("[1/1] ok"), std::string::npos) << resume.output;
  const auto rows = readIndex((out / "index.csv").string());
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].get("status"), "ok");
  EXPECT_EQ(rows[0].get("reused"), "");
}

TEST_F(SweepLockTest, RunThatFillsItsDiskIsAnErrorWithTheReason) {
  const fs::path sweep_file = dir_ / "full.toml";
  std::ofstream(sweep_file) << "name = \"full\"\n[[group]]\nname = \"g\"\n"
                            << "datasets = [\"kitti/10\"]\nvariants = [\"ns-qr-sqrt-f64\"]\n"
                            << "frames = 60\n";
  const fs::path out = dir_ / "out";
  test::CliResult result;
  {
    const test::FileSizeLimit limit(100 * 1024);  // the index and logs fit, a results file not
    result = runCli("sweep " + q(sweep_file) + " --out " + q(out));
  }
  EXPECT_EQ(result.exit_code, 1) << result.output;
  const auto rows = readIndex((out / "index.csv").string());
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].get("status"), "failed");
  EXPECT_EQ(rows[0].get("failure_kind"), "exit");
  EXPECT_EQ(rows[0].get("exit_code"), "1");
  EXPECT_EQ(rows[0].get("signal"), "");
  EXPECT_NE(rows[0].get("reason").find(std::strerror(EFBIG)), std::string::npos)
      << rows[0].get("reason");
  for (const auto& entry : fs::directory_iterator(out / "runs")) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos) << entry.path();
  }
}

}  // namespace
}  // namespace marglab::experiment
