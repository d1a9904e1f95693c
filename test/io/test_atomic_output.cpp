// Atomic outputs (core/common/atomic_file.h, core/io/hdf5.h): a failed write — disk full,
// file size limit, a rename refused — leaves the previous file at the path untouched, removes the
// temporary and says why; SIGINT/SIGTERM remove the temporaries (core/common/interrupt.h).

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "common/cli_runner.h"
#include "common/fault_injection.h"
#include "common/temp_dir.h"
#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/common/interrupt.h"
#include "core/common/source_dir.h"
#include "core/io/hdf5.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::readText;

class AtomicOutputTest : public test::TempDirTest {
 protected:
  std::string file(const std::string& name) const { return (dir_ / name).string(); }
  std::vector<std::string> listing(const fs::path& dir) const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) {
      names.push_back(entry.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
  }
};

template <typename F>
std::string inputErrorOf(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError thrown";
  return {};
}

// An HDF5 file of about 800 KB.
void writeLargeHdf5(const std::string& path) {
  h5::File f = h5::File::create(path);
  std::vector<double> values(100000);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = 0.5 * static_cast<double>(i);
  f.write("values", values);
  f.commit();
}

TEST_F(AtomicOutputTest, CommitReplacesThePreviousFileAndLeavesNoTemporary) {
  const std::string path = file("out.txt");
  writeFileAtomically(path, "old\n");
  {
    AtomicFile f(path);
    f.write("new ");
    f.write("text\n");
    EXPECT_EQ(readText(path), "old\n");  // nothing visible before the commit
    EXPECT_EQ(f.temporaryPath().rfind(path + ".tmp-" + std::to_string(::getpid()) + "-", 0), 0u);
    EXPECT_EQ(detail::liveTemporaryCount(), 1);
    f.commit();
  }
  EXPECT_EQ(readText(path), "new text\n");
  EXPECT_EQ(listing(dir_), std::vector<std::string>{"out.txt"});
  EXPECT_EQ(detail::liveTemporaryCount(), 0);
  {
    AtomicFile abandoned(path);
    abandoned.write("partial");
  }
  EXPECT_EQ(readText(path), "new text\n");
  EXPECT_EQ(listing(dir_), std::vector<std::string>{"out.txt"});
  EXPECT_EQ(detail::liveTemporaryCount(), 0);
}

TEST_F(AtomicOutputTest, FailedWriteKeepsThePreviousFileAndNamesTheReason) {
  const std::string path = file("table.csv");
  writeFileAtomically(path, "previous\n");
  const std::string big(256 * 1024, 'x');
  std::string message;
  {
    const test::FileSizeLimit limit(64 * 1024);
    message = inputErrorOf([&] { writeFileAtomically(path, big); });
  }
  EXPECT_NE(message.find(path + ": cannot write " + path + ".tmp-"), std::string::npos) << message;
  EXPECT_NE(message.find(std::strerror(EFBIG)), std::string::npos) << message;
  EXPECT_EQ(readText(path), "previous\n");
  EXPECT_EQ(listing(dir_), std::vector<std::string>{"table.csv"});
  EXPECT_EQ(detail::liveTemporaryCount(), 0);
}

// Item 9 of issue 18: the message named an empty temporary ("cannot rename  onto it").
TEST_F(AtomicOutputTest, RefusedRenameNamesTheTemporary) {
  const std::string target = file("a_folder");
  fs::create_directories(fs::path(target) / "inside");
  std::string message = inputErrorOf([&] { writeFileAtomically(target, "text"); });
  const std::string expected = "cannot rename " + target + ".tmp-" + std::to_string(::getpid());
  EXPECT_NE(message.find(expected), std::string::npos) << message;
  EXPECT_NE(message.find(" onto it: "), std::string::npos) << message;
  EXPECT_EQ(listing(dir_), std::vector<std::string>{"a_folder"});

  message = inputErrorOf([&] {
    h5::File f = h5::File::create(target);
    f.setAttr("x", 1);
    f.commit();
  });
  EXPECT_NE(message.find(expected), std::string::npos) << message;
  EXPECT_EQ(listing(dir_), std::vector<std::string>{"a_folder"});
}

TEST_F(AtomicOutputTest, Hdf5CommitBeyondTheFileSizeLimitFailsCleanly) {
  const std::string path = file("run.h5");
  writeLargeHdf5(path);
  const auto size = fs::file_size(path);
  std::string message;
  {
    const test::FileSizeLimit limit(64 * 1024);
    message = inputErrorOf([&] { writeLargeHdf5(path); });
  }
  EXPECT_NE(message.find(path + ": cannot write " + path + ".tmp-"), std::string::npos) << message;
  EXPECT_NE(message.find(std::strerror(EFBIG)), std::string::npos) << message;
  EXPECT_EQ(fs::file_size(path), size);
  EXPECT_EQ(h5::File::openReadOnly(path).readVector<double>("values")[99999], 49999.5);
  EXPECT_EQ(listing(dir_), std::vector<std::string>{"run.h5"});
  // The library is still sound: the next file is written and read back.
  writeLargeHdf5(file("next.h5"));
  EXPECT_EQ(h5::File::openReadOnly(file("next.h5")).readVector<double>("values").size(), 100000u);
}

TEST_F(AtomicOutputTest, Hdf5OnAFullDiskFailsCleanly) {
  const test::SmallTmpfs full(dir_ / "full", "200k");
  if (!full.mounted()) GTEST_SKIP() << full.reason();
  const std::string path = (full.dir() / "run.h5").string();
  const std::string message = inputErrorOf([&] { writeLargeHdf5(path); });
  EXPECT_NE(message.find(path + ": cannot write " + path + ".tmp-"), std::string::npos) << message;
  EXPECT_NE(message.find(std::strerror(ENOSPC)), std::string::npos) << message;
  EXPECT_TRUE(listing(full.dir()).empty());
}

// A child writing a temporary is interrupted: default handling (unlink, exit 128 + signal) and,
// inside an InterruptPolling scope, unwinding from throwIfInterrupted().
int interruptedChildExit(const std::string& path, int signal, bool polling) {
  int ready[2];
  if (pipe(ready) != 0) return -1;
  const pid_t pid = fork();
  if (pid == 0) {
    close(ready[0]);
    try {
      AtomicFile f(path);
      f.write("partial");
      std::optional<InterruptPolling> poll;
      if (polling) poll.emplace();
      // Blocked until sigsuspend: a signal cannot slip in between the check and the wait.
      sigset_t block, old;
      sigemptyset(&block);
      sigaddset(&block, SIGINT);
      sigaddset(&block, SIGTERM);
      sigaddset(&block, SIGHUP);
      sigprocmask(SIG_BLOCK, &block, &old);
      [[maybe_unused]] const ssize_t n = write(ready[1], "r", 1);
      for (;;) {
        throwIfInterrupted();
        sigsuspend(&old);
      }
    } catch (const Interrupted& e) {
      _exit(e.exitCode());
    }
  }
  close(ready[1]);
  char c = 0;
  const bool started = read(ready[0], &c, 1) == 1;
  close(ready[0]);
  if (started) kill(pid, signal);
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
}

TEST_F(AtomicOutputTest, InterruptRemovesTheTemporaries) {
  const std::string path = file("run.h5");
  writeFileAtomically(path, "previous");
  EXPECT_EQ(interruptedChildExit(path, SIGINT, false), 130);
  EXPECT_EQ(listing(dir_), std::vector<std::string>{"run.h5"});
  EXPECT_EQ(interruptedChildExit(path, SIGTERM, false), 143);
  EXPECT_EQ(listing(dir_), std::vector<std::string>{"run.h5"});
  EXPECT_EQ(interruptedChildExit(path, SIGINT, true), 130);
  EXPECT_EQ(listing(dir_), std::vector<std::string>{"run.h5"});
  EXPECT_EQ(interruptedChildExit(path, SIGTERM, true), 143);
  EXPECT_EQ(listing(dir_), std::vector<std::string>{"run.h5"});
  // Issue 38 item 7: every signal the process can catch.
  EXPECT_EQ(interruptedChildExit(path, SIGHUP, false), 129);
  EXPECT_EQ(listing(dir_), std::vector<std::string>{"run.h5"});
  EXPECT_EQ(readText(path), "previous");
}

// Issue 38 item 1: the rename replaced a device node or FIFO at the path with a regular file.
// A scratch node and FIFO, never the machine's own /dev/null.
TEST_F(AtomicOutputTest, DeviceNodesAndFifosAreRefusedNotReplaced) {
  std::vector<std::string> specials{file("fifo")};
  ASSERT_EQ(mkfifo(specials[0].c_str(), 0644), 0) << std::strerror(errno);
  if (mknod(file("null").c_str(), S_IFCHR | 0644, makedev(1, 3)) == 0) {
    specials.push_back(file("null"));
  }
  for (const std::string& path : specials) {
    std::string message = inputErrorOf([&] { writeFileAtomically(path, "text"); });
    EXPECT_NE(message.find(path + ": is a "), std::string::npos) << message;
    EXPECT_NE(message.find("not a regular file"), std::string::npos) << message;
    message = inputErrorOf([&] {
      h5::File f = h5::File::create(path);
      f.setAttr("x", 1);
      f.commit();
    });
    EXPECT_NE(message.find(path + ": is a "), std::string::npos) << message;
  }
  // A FIFO made at the path while its temporary is being written.
  const std::string late = file("late");
  {
    AtomicFile f(late);
    f.write("text");
    ASSERT_EQ(mkfifo(late.c_str(), 0644), 0);
    const std::string message = inputErrorOf([&] { f.commit(); });
    EXPECT_NE(message.find("is a FIFO"), std::string::npos) << message;
  }
  EXPECT_TRUE(fs::is_fifo(specials[0]));
  EXPECT_TRUE(fs::is_fifo(late));
  if (specials.size() > 1) {
    EXPECT_TRUE(fs::is_character_file(specials[1]));
  }
  EXPECT_EQ(listing(dir_).size(), specials.size() + 1);
  EXPECT_EQ(detail::liveTemporaryCount(), 0);
}

// The Python side (tools/scripts/atomic_save.py): test/io/atomic_save_test.py.
TEST(AtomicSave, PythonHelperKeepsThePreviousFileOnFailure) {
  if (std::system("python3 -c '' > /dev/null 2>&1") != 0) GTEST_SKIP() << "no python3 on PATH";
  const std::string source = sourceDir();
  const auto result = test::runShell("python3 '" + source + "/test/io/atomic_save_test.py' '" +
                                     source + "/tools/scripts'");
  EXPECT_EQ(result.exit_code, 0) << result.output;
}

}  // namespace
}  // namespace marglab
