// Bounded text inputs (core/io/text_input.h), issue 38 item 3: `run --config /dev/zero` grew to
// 24 GB. A file beyond the size bound, a line beyond the line bound and binary data are input
// errors naming the file; an endless FIFO stops at the bound. Scratch nodes and FIFOs only.

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <fstream>
#include <string>

#include "common/cli_runner.h"
#include "common/memory.h"
#include "common/temp_dir.h"
#include "core/common/error.h"
#include "core/io/text_input.h"

namespace marglab {
namespace {

std::string inputErrorOf(const std::string& path, TextLimits limits) {
  try {
    readTextInput(path, "the config file", limits);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError for " << path;
  return {};
}

// A child writes `line` to the FIFO forever (until the reader closes it: SIGPIPE).
pid_t feedForever(const std::string& fifo, const std::string& line) {
  const pid_t pid = fork();
  if (pid == 0) {
    signal(SIGPIPE, SIG_DFL);
    std::ofstream out(fifo);
    while (out << line) {
    }
    _exit(0);
  }
  return pid;
}

TEST(TextInput, ReadsTextWithinTheBounds) {
  const test::TempDir dir;
  std::ofstream(dir.file("a.toml")) << "[lm]\nmax_iterations = 5\n";
  EXPECT_EQ(readTextInput(dir.file("a.toml"), "the config file", {100, 30}),
            "[lm]\nmax_iterations = 5\n");
}

TEST(TextInput, RefusesBeyondTheBoundsAndBinaryData) {
  const test::TempDir dir;
  std::ofstream(dir.file("big.toml")) << std::string(40, '\n');
  EXPECT_NE(inputErrorOf(dir.file("big.toml"), {32, 10})
                .find(dir.file("big.toml") + ": larger than 32 bytes: expected the config file"),
            std::string::npos);
  std::ofstream(dir.file("long.toml")) << "a\nbb\n" << std::string(11, 'c') << "\n";
  EXPECT_NE(inputErrorOf(dir.file("long.toml"), {100, 10})
                .find(dir.file("long.toml") + ":3: line longer than 10 bytes"),
            std::string::npos);
  std::ofstream(dir.file("bin.toml")) << "a = 1\n" << std::string(3, '\0') << "\x81\xff";
  EXPECT_NE(
      inputErrorOf(dir.file("bin.toml"), {100, 10})
          .find(dir.file("bin.toml") + ":2: expected the config file as text, found binary data"),
      std::string::npos);
  EXPECT_NE(inputErrorOf(dir.file("missing.toml"), {100, 10}).find("cannot open the config file"),
            std::string::npos);
  EXPECT_NE(inputErrorOf(dir.path().string(), {100, 10}).find("cannot read the config file"),
            std::string::npos);
}

TEST(TextInput, EndlessDevicesAndFifosStopAtTheBound) {
  const test::TempDir dir;
  const std::string zero = dir.file("zero");
  if (mknod(zero.c_str(), S_IFCHR | 0644, makedev(1, 5)) == 0) {
    EXPECT_NE(inputErrorOf(zero, kSettingsTextLimits).find("found binary data"), std::string::npos);
  }
  const std::string fifo = dir.file("fifo");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0644), 0);
  const pid_t writer = feedForever(fifo, "a = 1\n");
  EXPECT_NE(inputErrorOf(fifo, kSettingsTextLimits).find("larger than 16 MiB"), std::string::npos);
  waitpid(writer, nullptr, 0);
}

// The CLI end to end, in a shell bounded to 4 GB of address space (the unbounded read exhausted
// it; exit 1 with the message now). The writer opens the FIFO in its own shell, away from the
// test's output pipe, and gives up after 60 s: a CLI that never reads cannot hang the test.
TEST(TextInput, RunConfigFromAnEndlessFifoIsAnInputError) {
#ifdef MARGLAB_UNDER_ASAN
  GTEST_SKIP() << "AddressSanitizer reserves terabytes of address space, which ulimit -v forbids";
#endif
  const test::TempDir dir;
  const std::string fifo = dir.file("config.toml");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0644), 0);
  const auto result =
      test::runShell("ulimit -v 4000000; (timeout 60 sh -c \"yes 'a = 1' > " + test::quote(fifo) +
                     "\" >/dev/null 2>&1 &) ; '" + test::cliPath() +
                     "' run --dataset kitti/10 --variant ns-qr-sqrt-f64 --frames 10 --config " +
                     test::quote(fifo) + " -o " + test::quote(dir.file("r.h5")));
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find(fifo + ": larger than 16 MiB: expected the config file"),
            std::string::npos)
      << result.output;
}

}  // namespace
}  // namespace marglab
