// `marglab bench` and `marglab run --dump-windows` through the real CLI.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>

#include <fmt/core.h>

#include "common/cli_runner.h"
#include "core/estimator/window_io.h"
#include "core/linalg/isa.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;

TEST(BenchCli, QuickJsonHasTheIssueKeysAndWritesTheTable) {
  const fs::path dir = fs::temp_directory_path() / "marglab_test_bench_cli";
  fs::remove_all(dir);
  const test::CliResult r = test::runCli(
      "bench --quick --frames 15 --json --variant sc-sc-sqp-f32 --out '" + dir.string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* key :
       {"speedup_ns_f32_over_sc_f64", "speedup_over_ceres_dense_schur", "speedup_over_ceres_best",
        "qr_kernel_peak_fraction", "realtime_factor_euroc_mh01", "realtime_factor_kitti00",
        "whole_run_opt_ratio_sc_f64_over_ns_f32_euroc_mh01", "peak_rss_mb_euroc_mh01"}) {
    // A finite positive number, not null.
    const std::regex value(std::string("\"") + key + "\": ([0-9.e+-]+)[,}]");
    std::smatch m;
    ASSERT_TRUE(std::regex_search(r.output, m, value)) << key << " in " << r.output;
    EXPECT_GT(std::stod(m[1].str()), 0) << key;
  }
  EXPECT_NE(r.output.find("\"run_frames_note\": \"whole-run RTFs over the first 15 frames\""),
            std::string::npos);
  // The bench's ISA (auto: the measured choice, one this CPU has), and the per-ISA figures of
  // every ISA it has.
  std::smatch isa;
  ASSERT_TRUE(std::regex_search(r.output, isa, std::regex("\"isa\": \"([a-z0-9]+)\""))) << r.output;
  EXPECT_TRUE(isaAvailable(resolveIsa(isa[1].str()))) << isa[1];
  for (const Isa isa : kAllIsas) {
    EXPECT_EQ(r.output.find(std::string("\"") + isaName(isa) + "\": {") != std::string::npos,
              isaAvailable(isa))
        << isaName(isa);
  }
  std::ifstream md(dir / "bench.md");
  const std::string table((std::istreambuf_iterator<char>(md)), {});
  EXPECT_NE(table.find("## Targets (issue #21)"), std::string::npos);
  for (const char* run : {"| euroc/MH_01_easy | ns-qr-sqrt-f32 | ok | 15 |",
                          "| kitti/00 | ns-qr-sqrt-f32 | ok | 15 |",
                          "| euroc/MH_01_easy | sc-sc-sq-f64 | ok | 15 |"}) {
    EXPECT_NE(table.find(run), std::string::npos) << run << " in " << table;
  }
  EXPECT_NE(table.find("| RTF KITTI 00 ≥ 40× |"), std::string::npos) << table;
  // The chosen variant beside the reference, in the table and the JSON.
  EXPECT_NE(table.find("| **all** | sc-sc-sqp-f32 | "), std::string::npos) << table;
  EXPECT_NE(r.output.find("\"variant\": \"sc-sc-sqp-f32\""), std::string::npos);
  EXPECT_TRUE(fs::exists(dir / "bench.json"));
  fs::remove_all(dir);
}

TEST(BenchCli, AnUnknownVariantIsAUsageErrorBeforeAnyTiming) {
  const test::CliResult r = test::runCli("bench --quick --no-runs --variant sc-sc-sqx-f32");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("unknown variant 'sc-sc-sqx-f32'"), std::string::npos) << r.output;
}

TEST(BenchCli, RunDumpsTheRequestedWindows) {
  const fs::path dir = fs::temp_directory_path() / "marglab_test_dump_cli";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const test::CliResult r = test::runCli(
      "run --dataset kitti/00 --variant ns-qr-sqrt-f64 --frames 6 --no-diagnostics "
      "--dump-windows 2,5 --dump-dir '" +
      (dir / "w").string() + "' -o '" + (dir / "r.h5").string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (int k : {2, 5}) {
    const fs::path f = dir / "w" / fmt::format("kitti-00_ns-qr-sqrt-f64_{:06d}.win.gz", k);
    ASSERT_TRUE(fs::exists(f)) << f;
    const WindowSnapshot w = readWindow(f.string());
    EXPECT_EQ(w.frame_index, k);
    EXPECT_EQ(w.variant, "ns-qr-sqrt-f64");
  }
  EXPECT_EQ(std::distance(fs::directory_iterator(dir / "w"), fs::directory_iterator{}), 2);
  const test::CliResult bad = test::runCli(
      "run --dataset kitti/00 --variant ns-qr-sqrt-f64 "
      "--dump-windows x -o '" +
      (dir / "r2.h5").string() + "'");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace marglab
