// The bench report's LM-iteration grid (core/bench/bench_report.h): each (elimination, precision)
// cell is the paper's variant and its own field, and the JSON names the fields the issue reads.

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/bench/bench_report.h"
#include "core/common/json.h"

namespace marglab {
namespace {

TEST(BenchReport, IterationCellsAreThePapersVariants) {
  std::vector<std::string> names;
  for (const IterationCell& cell : kIterationCells) names.push_back(cell.variant().name());
  EXPECT_EQ(names, (std::vector<std::string>{"ns-qr-sqrt-f32", "ns-qr-sqrt-f64", "sc-sc-sq-f32",
                                             "sc-sc-sq-f64"}));
}

TEST(BenchReport, EachCellHasItsOwnField) {
  IterationTimes t;
  for (std::size_t i = 0; i < kIterationCells.size(); ++i) t[kIterationCells[i]] = 1.0 + i;
  EXPECT_EQ(t.ns.f32, 1.0);
  EXPECT_EQ(t.ns.f64, 2.0);
  EXPECT_EQ(t.sc.f32, 3.0);
  EXPECT_EQ(t.sc.f64, 4.0);
  IterationTimes sum;
  sum += t;
  sum += t;
  EXPECT_EQ(sum.sc.f64, 8.0);
}

// Per-ISA and summed iteration times reach the JSON under lm_iteration_us_<cell>, and the markdown
// ratio is sc-f64 / ns-f32 of the window.
TEST(BenchReport, JsonAndMarkdownReadTheCells) {
  BenchReport r;
  r.isa = "sse2";
  WindowTimes w;
  w.name = "w";
  w.iteration.ns.f32 = 1e-6;
  w.iteration.ns.f64 = 2e-6;
  w.iteration.sc.f32 = 3e-6;
  w.iteration.sc.f64 = 4e-6;
  w.ns_mixed = 5e-6;
  r.windows.push_back(w);
  const Json j = Json::parse(benchJson(r));
  EXPECT_EQ(j["lm_iteration_us_ns_f32"], 1.0);
  EXPECT_EQ(j["lm_iteration_us_ns_f64"], 2.0);
  EXPECT_EQ(j["lm_iteration_us_sc_f64"], 4.0);
  EXPECT_EQ(j["lm_iteration_us_ns_mixed"], 5.0);
  EXPECT_TRUE(j["realtime_factor_euroc_mh01"].is_null());  // no whole runs
  EXPECT_NE(benchMarkdown(r).find("| w | 0 | 1.0 | 2.0 | 3.0 | 4.0 | 5.0 | 4.00 |"),
            std::string::npos);
}

}  // namespace
}  // namespace marglab
