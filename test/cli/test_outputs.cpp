// What `run` and `datasets simulate` leave behind when writing fails or is interrupted, and what
// they refuse to write (issue 18 items 1, 8, 10): a full disk or a file size limit is an error
// naming the file and the reason (exit 1), never a crash, with nothing at the final name and no
// temporary; SIGINT/SIGTERM exit 130/143 without a temporary; an output that is an input of the
// same command is refused before anything runs.

#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include "common/cli_runner.h"
#include "common/fault_injection.h"
#include "common/temp_dir.h"
#include "core/data/sequence.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::readText;
using test::runCli;

class OutputsCliTest : public test::TempDirTest {
 protected:
  std::string q(const fs::path& p) const { return "'" + p.string() + "'"; }
};

std::vector<std::string> listing(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

// A run of 60 frames writes ~250 kB; the track file of the whole sequence ~2 MB.
void expectCleanFailure(const fs::path& folder, const std::string& reason) {
  const std::string run_out = (folder / "r.h5").string();
  const auto run =
      runCli("run --dataset kitti/10 --variant ns-qr-sqrt-f64 --frames 60 -o '" + run_out + "'");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("marglab: error: " + run_out + ": cannot write " + run_out + ".tmp-"),
            std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find(reason), std::string::npos) << run.output;
  const std::string sim_out = (folder / "x.h5").string();
  const auto sim = runCli("datasets simulate --dataset kitti/10 -o '" + sim_out + "'");
  EXPECT_EQ(sim.exit_code, 1) << sim.output;
  EXPECT_NE(sim.output.find(sim_out + ": cannot write " + sim_out + ".tmp-"), std::string::npos)
      << sim.output;
  EXPECT_NE(sim.output.find(reason), std::string::npos) << sim.output;
  EXPECT_TRUE(listing(folder).empty());
}

TEST_F(OutputsCliTest, FullDiskIsAnErrorNotACrash) {
  const test::SmallTmpfs full(dir_ / "full", "200k");
  if (!full.mounted()) GTEST_SKIP() << full.reason();
  expectCleanFailure(full.dir(), std::strerror(ENOSPC));
}

TEST_F(OutputsCliTest, FileSizeLimitIsAnErrorNotACrash) {
  const test::FileSizeLimit limit(100 * 1024);  // inherited by the CLI, with SIGXFSZ ignored
  expectCleanFailure(dir_, std::strerror(EFBIG));
}

// Issue 18 item 8: `run --dataset SEQ -o SEQ/poses.txt` replaced the poses with HDF5.
TEST_F(OutputsCliTest, OutputsNeverReplaceAnInputOfTheSameCommand) {
  const fs::path seq = dir_ / "seq";
  fs::copy(fs::path(datasetsRoot()) / "kitti" / "10", seq);
  const std::string poses = readText(seq / "poses.txt.gz");
  const fs::path config = dir_ / "config.toml";
  std::ofstream(config) << "[lm]\nmax_iterations = 5\n";
  const auto tracks =
      runCli("datasets simulate --dataset " + q(seq) + " --frames 10 -o " + q(dir_ / "tracks.txt"));
  ASSERT_EQ(tracks.exit_code, 0) << tracks.output;
  fs::create_symlink(config, dir_ / "link.h5");

  const std::string run = "run --variant ns-qr-sqrt-f64 --frames 10 --dataset " + q(seq);
  struct Case {
    std::string command, output, input;
  };
  const std::vector<Case> cases = {
      {run + " -o " + q(seq / "poses.txt.gz"), (seq / "poses.txt.gz").string(), seq.string()},
      {run + " --config " + q(config) + " -o " + q(config), config.string(), config.string()},
      {run + " --config " + q(config) + " -o " + q(dir_ / "link.h5"), (dir_ / "link.h5").string(),
       config.string()},
      {run + " --tracks " + q(dir_ / "tracks.txt") + " -o " + q(dir_ / "tracks.txt"),
       (dir_ / "tracks.txt").string(), (dir_ / "tracks.txt").string()},
      {run + " -o " + q(seq / "calib.h5"), (seq / "calib.tum").string(), seq.string()},
      {"datasets simulate --dataset " + q(seq) + " -o " + q(seq / "times.txt.gz"),
       (seq / "times.txt.gz").string(), seq.string()},
  };
  fs::copy_file(seq / "calib.txt", seq / "calib.tum");  // the TUM file of -o calib.h5
  for (const Case& c : cases) {
    const auto result = runCli(c.command);
    EXPECT_EQ(result.exit_code, 1) << c.command << "\n" << result.output;
    EXPECT_NE(result.output.find("marglab: error: " + c.output + ": "), std::string::npos)
        << result.output;
    EXPECT_NE(result.output.find(c.input), std::string::npos) << result.output;
    EXPECT_NE(result.output.find("input"), std::string::npos) << result.output;
  }
  EXPECT_EQ(readText(seq / "poses.txt.gz"), poses);
  EXPECT_EQ(readText(config), "[lm]\nmax_iterations = 5\n");
  EXPECT_EQ(runCli("datasets check " + q(seq)).exit_code, 0);
  // A new file inside the dataset folder replaces nothing.
  const auto fresh = runCli(run + " -o " + q(seq / "fresh.h5"));
  EXPECT_EQ(fresh.exit_code, 0) << fresh.output;
}

// Starts `marglab run` on the whole KITTI 10 (minutes of work) with output in dir; returns its
// pid once its results temporary exists (the frame loop is about to start or running).
pid_t startRunAndWaitForTemporary(const fs::path& dir) {
  const pid_t pid = fork();
  if (pid == 0) {
    // A shell without job control starts background commands with SIGINT ignored.
    signal(SIGINT, SIG_DFL);
    signal(SIGTERM, SIG_DFL);
    const int null_fd = open("/dev/null", O_WRONLY);
    dup2(null_fd, 1);
    dup2(null_fd, 2);
    execl(test::cliPath(), test::cliPath(), "run", "--dataset", "kitti/10", "--variant",
          "ns-qr-sqrt-f64", "-o", (dir / "r.h5").c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // A wait for an event, bounded so that a broken build fails instead of hanging.
  for (int i = 0; i < 6000; ++i) {
    for (const std::string& name : listing(dir)) {
      if (name.rfind("r.h5.tmp-", 0) == 0) return pid;
    }
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) return -1;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
  return -1;
}

// Issue 18 item 10: an interrupted run left RUN.h5.tmp-PID-0.
TEST_F(OutputsCliTest, InterruptedRunExitsWith128PlusSignalAndLeavesNoTemporary) {
  for (const int signal : {SIGINT, SIGTERM}) {
    const pid_t pid = startRunAndWaitForTemporary(dir_);
    ASSERT_GT(pid, 0) << "the run never created its temporary";
    ASSERT_EQ(kill(pid, signal), 0);
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status);
    EXPECT_EQ(WEXITSTATUS(status), 128 + signal);
    EXPECT_TRUE(listing(dir_).empty()) << listing(dir_).front();
  }
}

}  // namespace
}  // namespace marglab
