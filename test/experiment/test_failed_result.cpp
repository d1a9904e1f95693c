// Which failed runs are results of a sweep (a complete results file: the estimator failed
// numerically or lost the scene) and which are failures of its processes (crash, kill, timeout,
// error): the sweep's exit code and its summary depend on it.

#include <gtest/gtest.h>

#include "core/experiment/sweep_common.h"

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

}  // namespace
}  // namespace marglab::experiment
