// Which failed runs are results of a sweep (a complete results file: the estimator failed
// numerically or lost the scene) and which are failures of its processes (crash, kill, timeout,
// error): the sweep's exit code and its summary depend on it.

#include <gtest/gtest.h>

#include <fstream>
#include <vector>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/experiment/sweep_common.h"
#include "core/experiment/sweep_index.h"

namespace marglab::experiment {
namespace {

IndexRow row(const std::string& status, const std::string& kind) {
  IndexRow r;
  r.set("status", status);
  r.set("failure_kind", kind);
  return r;
}

TEST(FailedResult, NumericalAndTrackingFailuresAreResults) {
  EXPECT_TRUE(detail::isFailedResult(row("failed", "numerical")));
  EXPECT_TRUE(detail::isFailedResult(row("failed", "tracking")));
  for (const char* kind : {"error", "timeout", "signal", "cancelled", ""}) {
    EXPECT_FALSE(detail::isFailedResult(row("failed", kind))) << kind;
  }
  EXPECT_FALSE(detail::isFailedResult(row("ok", "")));
}

IndexRow row(const std::string& status, const std::string& kind, const std::string& exit_code,
             int n) {
  IndexRow r = row(status, kind);
  r.set("exit_code", exit_code);
  r.set("id", "r" + std::to_string(n));
  r.set("results", "runs/r" + std::to_string(n) + ".h5");
  r.set("log", "logs/r" + std::to_string(n) + ".log");
  r.set("command", "marglab run");
  return r;
}

// Issue 38 (low): the summary counted a run that lost tracking as "failed numerically" and a run
// that refused its input (exit 1 without results, or could not start) as "crashed or killed".
// Each failure_kind now has its category; the exit code still fails the sweep for errors and
// crashes only.
class FailureSummary : public test::TempDirTest {};

TEST_F(FailureSummary, EachFailureKindIsCountedInItsOwnCategory) {
  FailureCounts counts;
  int n = 0;
  for (const auto& [kind, code] :
       std::vector<std::pair<const char*, const char*>>{{"numerical", "1"},
                                                        {"tracking", "1"},
                                                        {"exit", "1"},
                                                        {"exit", "2"},
                                                        {"error", ""},
                                                        {"signal", ""},
                                                        {"timeout", ""},
                                                        {"exit", "134"}}) {
    counts.add(row("failed", kind, code, n++));
  }
  EXPECT_EQ(counts.numerical, 1);
  EXPECT_EQ(counts.tracking, 1);
  EXPECT_EQ(counts.error, 3);
  EXPECT_EQ(counts.crashed, 3);
  EXPECT_EQ(counts.processFailures(), 6);
  EXPECT_EQ(counts.text(),
            "1 failed numerically, 1 lost tracking, 3 ended with an error, 3 crashed or killed "
            "(1 exit, 1 signal, 1 timeout)");
  // Without runs in the new categories the line reads as it always did.
  FailureCounts plain;
  plain.add(row("failed", "numerical", "1", 0));
  EXPECT_EQ(plain.text(), "1 failed numerically, 0 crashed or killed");
}

// The line `sweep --status` prints for a local sweep's folder (the Slurm backend's report; the
// local runner prints the same FailureCounts::text()).
TEST_F(FailureSummary, SweepStatusCountsTrackingAndErrorsApart) {
  std::vector<IndexRow> rows = {row("ok", "", "0", 0),
                                row("failed", "numerical", "1", 1),
                                row("failed", "tracking", "1", 2),
                                row("failed", "exit", "1", 3),
                                row("failed", "error", "", 4),
                                row("failed", "signal", "", 5)};
  writeIndex((dir_ / "index.csv").string(), rows);
  std::ofstream(dir_ / "sweep.toml") << "name = \"s\"\n";
  const auto status = test::runCli("sweep --status " + test::quote(dir_));
  EXPECT_EQ(status.exit_code, 1) << status.output;
  EXPECT_NE(status.output.find(": 1 ok, 1 failed numerically, 1 lost tracking, 2 ended with an "
                               "error, 1 crashed or killed (1 signal) in "),
            std::string::npos)
      << status.output;
}

}  // namespace
}  // namespace marglab::experiment
