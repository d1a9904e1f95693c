// `marglab bench --variant` (core/bench/variant_bench.h): the chosen variants are timed beside the
// reference ns-qr-sqrt-f32 on a shipped window, a variant that cannot run on a window is recorded
// with its reason instead of being timed, and the table and JSON total a variant only where it ran
// on every window.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "core/bench/perf_suite.h"
#include "core/bench/variant_bench.h"

namespace marglab {
namespace {

std::vector<Variant> parsed(const std::vector<std::string>& names) {
  std::vector<Variant> out;
  for (const std::string& n : names) out.push_back(Variant::parse(n));
  return out;
}

TEST(VariantBench, TimesTheReferenceFirstThenEachVariantOnce) {
  const std::vector<NamedWindow> windows = loadWindows();
  ASSERT_FALSE(windows.empty());
  const std::vector<VariantWindowTimes> t =
      timeVariants(windows.front().window,
                   parsed({"sc-sc-sqp-f32", "ns-qr-sqrt-f32", "sc-sc-sqrtp-f64"}), 1, 1e-4);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t[0].variant, "ns-qr-sqrt-f32");
  EXPECT_EQ(t[1].variant, "sc-sc-sqp-f32");
  EXPECT_EQ(t[2].variant, "sc-sc-sqrtp-f64");
  for (const VariantWindowTimes& v : t) {
    EXPECT_TRUE(v.failure.empty()) << v.variant << ": " << v.failure;
    EXPECT_GT(v.iteration_s, 0) << v.variant;
    EXPECT_GT(v.marginalization_s, 0) << v.variant;
  }
}

// A NaN in the prior: no variant can solve the window; each says so instead of throwing.
TEST(VariantBench, AVariantThatFailsOnAWindowIsRecordedNotTimed) {
  std::vector<NamedWindow> windows = loadWindows();
  ASSERT_FALSE(windows.empty());
  WindowSnapshot w = windows.front().window;
  ASSERT_GT(w.prior_J.size(), 0);
  w.prior_J(0, 0) = std::numeric_limits<double>::quiet_NaN();
  const std::vector<VariantWindowTimes> t = timeVariants(w, parsed({"sc-sc-sqp-f32"}), 1, 1e-4);
  ASSERT_EQ(t.size(), 2u);
  for (const VariantWindowTimes& v : t) {
    EXPECT_FALSE(v.failure.empty()) << v.variant;
    EXPECT_NE(v.failure.find("non-finite"), std::string::npos) << v.variant << ": " << v.failure;
    EXPECT_EQ(v.iteration_s, 0) << v.variant;
  }
}

VariantBench twoWindows() {
  VariantBench b;
  b.windows = {"a", "b"};
  b.times = {
      {{"ns-qr-sqrt-f32", "", 1e-6, 2e-6}, {"sc-sc-sqp-f32", "", 3e-6, 2e-6}},
      {{"ns-qr-sqrt-f32", "", 1e-6, 2e-6}, {"sc-sc-sqp-f32", "not positive definite", 0, 0}}};
  return b;
}

TEST(VariantBench, TotalsOnlyVariantsThatRanOnEveryWindow) {
  VariantBench b = twoWindows();
  std::string md = variantBenchMarkdown(b, "sse2");
  EXPECT_NE(md.find("| a | sc-sc-sqp-f32 | 3.0 | 3.00 | 2.0 | 1.00 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| b | sc-sc-sqp-f32 | failed: not positive definite |"), std::string::npos);
  EXPECT_NE(md.find("| **all** | ns-qr-sqrt-f32 | 2.0 | **1.00** | 4.0 | **1.00** |"),
            std::string::npos);
  EXPECT_NE(md.find("| **all** | sc-sc-sqp-f32 | failed on 1 of 2 windows |"), std::string::npos);
  Json j = variantBenchJson(b);
  ASSERT_EQ(j.size(), 2u);
  EXPECT_EQ(j[0]["lm_iteration_us"], 2.0);
  EXPECT_TRUE(j[1]["lm_iteration_us"].is_null());
  EXPECT_EQ(j[1]["failed_windows"]["b"], "not positive definite");

  b.times[1][1] = {"sc-sc-sqp-f32", "", 5e-6, 2e-6};
  j = variantBenchJson(b);
  EXPECT_EQ(j[1]["lm_iteration_us"], 8.0);
  EXPECT_EQ(j[1]["lm_iteration_ratio"], 4.0);
  EXPECT_EQ(j[1]["marginalization_ratio"], 1.0);
}

TEST(VariantBench, NoChosenVariantNoSection) {
  VariantBench b;
  EXPECT_EQ(variantBenchMarkdown(b, "sse2"), "");
  b.windows = {"a"};
  b.times = {{{"ns-qr-sqrt-f32", "", 1e-6, 2e-6}}};
  EXPECT_EQ(variantBenchMarkdown(b, "sse2"), "");
}

}  // namespace
}  // namespace marglab
