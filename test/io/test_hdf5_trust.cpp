// The trust boundary (core/io/hdf5_trust.h): every way a read can end in the child reaches the
// caller as an InputError naming the file and what happened, and nothing of the read happens in
// the caller. Each ending is made deterministically (a loop that never ends, a sleep that never
// ends, a raised signal, a request far beyond the budget); the limits only bound how long the
// test takes to see it.

#include "core/io/hdf5_trust.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/memory.h"
#include "core/common/error.h"

namespace marglab::h5 {
namespace {

const std::string kPath = "user/tracks.h5";

// The message of the InputError the boundary throws for `read` (fails the test if none).
std::string refusal(const std::function<void()>& read, const ReadLimits& limits = {}) {
  try {
    checkReadableInChild(kPath, read, limits);
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), kPath) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return {};
}

TEST(Hdf5Trust, ReadThatEndsPassesAndLeavesTheCallerAlone) {
  int touched = 0;
  checkReadableInChild(kPath, [&touched] { touched = 1; });
  EXPECT_EQ(touched, 0);  // the child's copy was touched, not ours
}

TEST(Hdf5Trust, InputErrorOfTheChildIsThrownAsItWas) {
  try {
    checkReadableInChild(kPath, [] { throw InputError("other.h5", 7, "/frames: no such group"); });
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "other.h5");
    EXPECT_EQ(e.line(), 7);
    EXPECT_EQ(e.detail(), "/frames: no such group");
  }
}

TEST(Hdf5Trust, OtherExceptionIsAnInputErrorNamingTheFile) {
  const std::string message = refusal([] { throw std::runtime_error("vector::_M_fill_insert"); });
  EXPECT_EQ(message, kPath + ": reading it failed: vector::_M_fill_insert");
}

// Under ASan a segmentation fault is ASan's report, which aborts (abort_on_error=1).
TEST(Hdf5Trust, CrashIsAnInputErrorNamingTheSignal) {
  const std::string message = refusal([] { std::raise(SIGSEGV); });
#ifdef MARGLAB_UNDER_ASAN
  const std::string signal = "signal 6, ";
#else
  const std::string signal = "signal 11, ";
#endif
  EXPECT_NE(message.find(kPath + ": reading it crashed (" + signal), std::string::npos) << message;
}

TEST(Hdf5Trust, EndlessLoopIsStoppedAtTheCpuLimit) {
  ReadLimits limits;
  limits.cpu_seconds = 1;
  const std::string message = refusal(
      [] {
        for (volatile unsigned i = 0;; i = i + 1) {
        }
      },
      limits);
  EXPECT_NE(message.find("reading it took more than 1 s of CPU time"), std::string::npos)
      << message;
}

TEST(Hdf5Trust, ReadThatNeverEndsIsStoppedAtTheTimeout) {
  ReadLimits limits;
  limits.wall_seconds = 1;
  const std::string message = refusal([] { ::pause(); }, limits);
  EXPECT_NE(message.find("reading it took more than 1 s ("), std::string::npos) << message;
}

// 64 GiB against a budget of 256 MiB: refused in the child (std::bad_alloc; under ASan its
// out-of-memory report ends the child), never allocated here.
TEST(Hdf5Trust, AllocationBeyondTheBudgetIsRefusedInTheChild) {
  ReadLimits limits;
  limits.address_space_bytes = std::uint64_t{256} << 20;
  const long rss_before = test::maxRssKb();
  const std::string message = refusal(
      [] {
        std::vector<char> huge(std::size_t{64} << 30, 1);
        std::exit(huge[12345]);
      },
      limits);
#ifdef MARGLAB_UNDER_ASAN
  EXPECT_NE(message.find("reading it crashed (signal 6"), std::string::npos) << message;
#else
  EXPECT_EQ(message, kPath +
                         ": reading it needed more than 256 MiB of memory: the file claims "
                         "sizes it does not hold");
#endif
  EXPECT_LT(test::maxRssKb() - rss_before, 100 * 1024);
}

}  // namespace
}  // namespace marglab::h5
