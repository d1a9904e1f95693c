// What `run` and `datasets simulate` leave behind when writing fails or is interrupted, and what
// they refuse to write (issue 18 items 1, 8, 10): a full disk or a file size limit is an error
// naming the file and the reason (exit 1), never a crash, with nothing at the final name and no
// temporary; SIGINT/SIGTERM exit 130/143 without a temporary; an output that is an input of the
// same command is refused before anything runs.

#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
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

// Issue 38 item 7: with SIGXFSZ at its default action (a shell's `ulimit -f`), the signal killed
// the writer and left its temporary.
TEST_F(OutputsCliTest, FileSizeLimitWithTheDefaultSignalLeavesNoTemporary) {
  const fs::path out = dir_ / "x.h5";
  const auto result =
      test::runShell("trap - XFSZ; ulimit -f 100; '" + std::string(test::cliPath()) +
                     "' datasets simulate --dataset kitti/10 -o " + q(out));
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find(std::strerror(EFBIG)), std::string::npos) << result.output;
  EXPECT_TRUE(listing(dir_).empty()) << listing(dir_).front();
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
      {run + " -o " + q(dir_ / "calib.h5"), (dir_ / "calib.tum").string(),
       (seq / "calib.txt").string()},
      {"datasets simulate --dataset " + q(seq) + " -o " + q(seq / "times.txt.gz"),
       (seq / "times.txt.gz").string(), seq.string()},
  };
  fs::create_symlink(seq / "calib.txt", dir_ / "calib.tum");  // the TUM file of -o calib.h5
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
}

void expectRefused(const std::string& command, const std::string& output,
                   const std::string& input) {
  const auto result = runCli(command);
  EXPECT_EQ(result.exit_code, 1) << command << "\n" << result.output;
  EXPECT_NE(result.output.find("marglab: error: " + output + ": "), std::string::npos)
      << result.output;
  EXPECT_NE(result.output.find(input), std::string::npos) << result.output;
}

// Issue 38 item 2: the ground truth of KITTI's official layout lies outside the sequence folder
// (dataset/poses/NN.txt); a new file in an input folder was accepted once, refused the second
// time; `datasets track --config fe.toml -o fe.toml` replaced its own config.
TEST_F(OutputsCliTest, OutputsNeverReplaceAnyInputNorWriteIntoAnInputFolder) {
  const fs::path root = dir_ / "K" / "dataset";
  const fs::path seq = root / "sequences" / "06";
  fs::create_directories(seq);
  fs::create_directories(root / "poses");
  for (const char* name : {"times.txt.gz", "calib.txt"}) {
    fs::copy_file(fs::path(datasetsRoot()) / "kitti" / "10" / name, seq / name);
  }
  const fs::path poses = root / "poses" / "06.txt.gz";
  fs::copy_file(fs::path(datasetsRoot()) / "kitti" / "10" / "poses.txt.gz", poses);
  const std::string gt = readText(poses);
  fs::create_hard_link(poses, dir_ / "hard.h5");
  const fs::path config = dir_ / "fe.toml";
  std::ofstream(config) << "[frontend]\n";

  const std::string run = "run --variant ns-qr-sqrt-f64 --frames 10 --dataset " + q(seq);
  expectRefused(run + " -o " + q(poses), poses.string(), poses.string());
  expectRefused(run + " -o " + q(dir_ / "hard.h5"), (dir_ / "hard.h5").string(), poses.string());
  expectRefused("datasets simulate --dataset " + q(seq) + " -o " + q(poses), poses.string(),
                poses.string());
  // New files in an input folder, every time.
  for (int attempt = 0; attempt < 2; ++attempt) {
    expectRefused(run + " -o " + q(seq / "fresh.h5"), (seq / "fresh.h5").string(), seq.string());
  }
  const std::string shipped = (fs::path(datasetsRoot()) / "kitti" / "06_images").string();
  const std::string new_tracks = shipped + "/new_tracks.h5";
  expectRefused("datasets track --dataset kitti/06_images --frames 2 -o " + q(new_tracks),
                new_tracks, datasetsRoot());
  expectRefused("datasets track --dataset kitti/06_images --frames 2 --config " + q(config) +
                    " -o " + q(config),
                config.string(), config.string());
  EXPECT_FALSE(fs::exists(new_tracks));
  EXPECT_EQ(readText(poses), gt);
  EXPECT_EQ(readText(config), "[frontend]\n");
  EXPECT_EQ(listing(seq), (std::vector<std::string>{"calib.txt", "times.txt.gz"}));
}

// Issue 38 item 1: `run -o /dev/null` replaced the device node with a 484 KB HDF5 file (the
// temporary renamed onto it). A scratch node and FIFO, never the machine's own /dev/null.
TEST_F(OutputsCliTest, DeviceNodesAndFifosAreRefusedNotReplaced) {
  const fs::path node = dir_ / "null";
  const fs::path fifo = dir_ / "fifo";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0644), 0) << std::strerror(errno);
  const bool have_node = mknod(node.c_str(), S_IFCHR | 0644, makedev(1, 3)) == 0;
  const std::string run = "run --dataset kitti/10 --variant ns-qr-sqrt-f32 --frames 10 -o ";
  std::vector<std::pair<std::string, fs::path>> cases = {
      {run + q(fifo), fifo},
      {"datasets simulate --dataset kitti/10 --frames 10 -o " + q(fifo), fifo},
      {"datasets track --dataset kitti/06_images --frames 2 -o " + q(fifo), fifo},
  };
  fs::create_symlink(fifo, dir_ / "r.tum");  // the TUM trajectory beside -o r.h5
  cases.push_back({run + q(dir_ / "r.h5"), dir_ / "r.tum"});
  if (have_node) cases.push_back({run + q(node), node});
  for (const auto& [command, refused] : cases) {
    const auto result = runCli(command);
    EXPECT_EQ(result.exit_code, 1) << command << "\n" << result.output;
    EXPECT_NE(result.output.find("marglab: error: " + refused.string() + ": is a "),
              std::string::npos)
        << result.output;
  }
  EXPECT_TRUE(fs::is_fifo(fifo));
  if (have_node) {
    EXPECT_TRUE(fs::is_character_file(node));
  }
  EXPECT_FALSE(fs::exists(dir_ / "r.h5"));
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
