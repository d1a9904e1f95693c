// `--isa auto` by measurement (core/bench/isa_choice.h, issue #38): the tie rule, the cache that
// decides once per machine and build (and survives damage), the results file's record of the
// choice, and parallel first runs that agree on one ISA.

#include "core/bench/isa_choice.h"

#include <gtest/gtest.h>

#include <toml++/toml.h>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/cli_runner.h"
#include "core/io/results_file.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;

TEST(IsaChoice, TheNarrowestIsaWithinOnePercentOfTheFastestIsTaken) {
  EXPECT_EQ(fastestIsa({{Isa::kSse2, 2.0}, {Isa::kAvx2, 1.0}, {Isa::kAvx512, 0.995}}), Isa::kAvx2);
  EXPECT_EQ(fastestIsa({{Isa::kSse2, 2.0}, {Isa::kAvx2, 1.0}, {Isa::kAvx512, 0.98}}), Isa::kAvx512);
  EXPECT_EQ(fastestIsa({{Isa::kSse2, 1.0}, {Isa::kAvx2, 1.2}}), Isa::kSse2);
  EXPECT_EQ(fastestIsa({}), bestIsa());
}

class IsaCacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("marglab_test_isa_choice_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    cache_ = dir_ / "isa_choice.toml";
    ::setenv("MARGLAB_ISA_CACHE", cache_.c_str(), 1);
  }
  void TearDown() override {
    ::unsetenv("MARGLAB_ISA_CACHE");
    fs::remove_all(dir_);
  }
  static bool severalIsas() { return isaAvailable(Isa::kAvx2); }

  fs::path dir_, cache_;
};

TEST_F(IsaCacheTest, MeasuredOnceThenTheCacheDecides) {
  if (!severalIsas()) GTEST_SKIP() << "one ISA available: nothing to choose";
  EXPECT_EQ(isaCachePath(), cache_.string());
  const IsaChoice first = chooseAutoIsa();
  ASSERT_TRUE(fs::is_regular_file(cache_));
  EXPECT_EQ(first.isa, fastestIsa(first.timings));
  EXPECT_NE(first.how.find("auto: measured fastest (sse2 "), std::string::npos) << first.how;
  EXPECT_NE(first.how.find("cached in " + cache_.string()), std::string::npos) << first.how;

  const IsaChoice again = chooseAutoIsa();
  EXPECT_EQ(again.isa, first.isa);
  EXPECT_EQ(again.timings.size(), first.timings.size());

  // The cache, not a new measurement, decides: an entry saying sse2 (slowest) is taken.
  toml::table cache = toml::parse_file(cache_.string());
  ASSERT_EQ(cache.size(), 1u);
  cache.begin()->second.as_table()->insert_or_assign("isa", "sse2");
  std::ofstream(cache_) << cache;
  EXPECT_EQ(chooseAutoIsa().isa, Isa::kSse2);

  // A damaged cache is measured again and rewritten.
  std::ofstream(cache_) << "[[[ not toml\n";
  const IsaChoice repaired = chooseAutoIsa();
  EXPECT_NE(repaired.how.find("cached in"), std::string::npos) << repaired.how;
  EXPECT_NO_THROW(toml::parse_file(cache_.string()));
}

// Through the CLI: the results file records the ISA and how it was chosen; the parallel first runs
// of a sweep (here two at once, the cache empty) measure once, under the cache's lock, and agree.
TEST_F(IsaCacheTest, RunsRecordTheChoiceAndParallelFirstRunsAgree) {
  const std::string env = "MARGLAB_ISA_CACHE=" + test::quote(cache_) + " ";
  const auto run = [&](const std::string& name, const std::string& isa) {
    return env + "'" + test::cliPath() + "'" +
           " run --dataset kitti/04 --variant ns-qr-sqrt-f32 --frames 5 --no-diagnostics " + isa +
           " -o " + test::quote(dir_ / (name + ".h5")) + " > " +
           test::quote(dir_ / (name + ".log"));
  };
  const auto r = test::runShell("(" + run("a", "") + " & " + run("b", "") + " & wait)");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const RunMetadata a = ResultsReader((dir_ / "a.h5").string()).info().metadata;
  const RunMetadata b = ResultsReader((dir_ / "b.h5").string()).info().metadata;
  EXPECT_EQ(a.isa, b.isa);
  EXPECT_EQ(a.isa_choice.rfind("auto: ", 0), 0u) << a.isa_choice;
  if (severalIsas()) {
    EXPECT_NE(a.isa_choice.find("measured fastest"), std::string::npos) << a.isa_choice;
    EXPECT_EQ(toml::parse_file(cache_.string()).size(), 1u);
  }
  ASSERT_EQ(test::runShell(run("c", "--isa sse2")).exit_code, 0);
  const RunMetadata c = ResultsReader((dir_ / "c.h5").string()).info().metadata;
  EXPECT_EQ(c.isa, "sse2");
  EXPECT_EQ(c.isa_choice, "--isa sse2");
}

}  // namespace
}  // namespace marglab
