// Seed statistics of Tables 1 and 2 and the seed claim table (issue #19) from a small synthetic
// sweep: every mean, std and failure count equals the one computed here from the ATEs the results
// files hold, a cell is `x n/n` only when every seed failed, the statistics switch on by themselves
// only for a table with several seeds per cell, and `--seeds off` keeps the single-value tables; a
// folder without its results files gives the same tables from its index.

#include <gtest/gtest.h>

#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/common/statistics.h"
#include "core/experiment/sweep_common.h"
#include "core/experiment/sweep_index.h"
#include "core/experiment/tables.h"
#include "core/io/results_file.h"

namespace marglab::experiment {
namespace {

namespace fs = std::filesystem;
using test::readText;

double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

// Sample standard deviation, two-pass.
double sampleStdOf(const std::vector<double>& v) {
  const double m = mean(v);
  double s = 0;
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}

class SeedTables : public test::TempDirTest {
 protected:
  void SetUp() override { fs::create_directories(dir_ / "sweep" / "runs"); }

  // A run with a trajectory error that depends on the salt; its index row. Returns the ATE the
  // results file holds (/summary ate_rmse).
  double addRun(const std::string& dataset, const std::string& variant, int seed, double salt,
                RunStatus status = RunStatus::kOk, const std::string& frames = "0") {
    const std::string sequence = dataset.substr(dataset.find('/') + 1);
    const std::string id =
        fmt::format("g{}__{}__{}__s{}", frames == "0" ? "" : frames, sequence, variant, seed);
    const std::string results = "runs/" + id + ".h5";
    RunMetadata m;
    m.dataset = dataset.substr(0, dataset.find('/'));
    m.sequence = sequence;
    m.variant = variant;
    m.precision = variant.substr(variant.size() - 3);
    m.mode = m.dataset == "kitti" ? "vo" : "vio";
    m.seed = static_cast<std::uint64_t>(seed);
    m.config_toml = "[window]\nmax_kfs = 7\n";
    ResultsWriter w = ResultsWriter::create((dir_ / "sweep" / results).string(), m);
    for (int i = 0; i < 20; ++i) {
      FrameRecord f;
      f.t_ns = 1'000'000'000LL + i * 50'000'000LL;
      f.p_gt = Eigen::Vector3d(0.1 * i, std::sin(0.2 * i), 0.05 * i * i);
      f.p_est = f.p_gt + salt * Eigen::Vector3d(std::cos(i), std::sin(3 * i), 0.3);
      w.appendFrame(f);
    }
    const double ate =
        w.finish(RunSummary{}, status, status == RunStatus::kOk ? -1 : 19, "test").ate_rmse;
    IndexRow row;
    row.set("id", id);
    row.set("group", "g");
    row.set("dataset", dataset);
    row.set("variant", variant);
    row.set("seed", std::to_string(seed));
    row.set("frames", frames);
    row.set("override", "");
    row.set("status", status == RunStatus::kOk ? "ok" : "failed");
    row.set("results", results);
    rows_.push_back(row);
    return ate;
  }

  fs::path writeTablesOf(SeedStats seeds) {
    writeIndex((dir_ / "sweep" / "index.csv").string(), rows_);
    TablesRequest request;
    request.dirs = {(dir_ / "sweep").string()};
    request.out = (dir_ / "tables").string();
    request.seeds = seeds;
    writeTables(request, nullptr);
    return dir_ / "tables";
  }

  // (table, row, variant) → CSV fields of a tables*.csv; `col` gives a column's index.
  struct Csv {
    std::vector<std::string> header;
    std::map<std::string, std::vector<std::string>> rows;
    std::size_t col(const std::string& name) const {
      const auto it = std::find(header.begin(), header.end(), name);
      EXPECT_NE(it, header.end()) << name;
      return static_cast<std::size_t>(it - header.begin());
    }
    const std::string& at(const std::string& key, const std::string& column) const {
      static const std::string kNone = "<none>";
      const auto it = rows.find(key);
      EXPECT_NE(it, rows.end()) << key;
      return it == rows.end() ? kNone : it->second[col(column)];
    }
  };
  static Csv readCsv(const fs::path& path, const std::vector<std::string>& key_columns) {
    const auto csv = parseCsv(readText(path), path.string());
    Csv out;
    out.header = csv.front();
    for (std::size_t r = 1; r < csv.size(); ++r) {
      std::string key;
      for (const std::string& c : key_columns) key += (key.empty() ? "" : "|") + csv[r][out.col(c)];
      out.rows[key] = csv[r];
    }
    return out;
  }

  std::vector<IndexRow> rows_;
};

TEST_F(SeedTables, CellsAreMeanStdAndFailureCountsOfTheResultsFiles) {
  const std::string mh = "euroc/MH_03_medium", room = "tumvi/room1", kitti = "kitti/10";
  std::map<std::string, std::vector<double>> ate;  // dataset|variant → ATE of the ok seeds
  for (int s = 1; s <= 3; ++s) {
    ate[mh + "|ns-qr-sqrt-f64"].push_back(addRun(mh, "ns-qr-sqrt-f64", s, 1e-3 * s));
    // √-f32 close to f64 on MH_03, far from it on room1; its seed 3 fails on room1.
    ate[mh + "|ns-qr-sqrt-f32"].push_back(addRun(mh, "ns-qr-sqrt-f32", s, 1e-3 * s + 1e-5));
    ate[room + "|ns-qr-sqrt-f64"].push_back(addRun(room, "ns-qr-sqrt-f64", s, 2e-3 + 1e-4 * s));
    if (s < 3) ate[room + "|ns-qr-sqrt-f32"].push_back(addRun(room, "ns-qr-sqrt-f32", s, 9e-3 * s));
    addRun(mh, "sc-sc-sq-f32", s, 0.1, RunStatus::kFailed);
  }
  addRun(room, "ns-qr-sqrt-f32", 3, 0.1, RunStatus::kFailed);
  // KITTI: one seed per cell, so Table 2 keeps single values under --seeds auto.
  const double kitti_64 = addRun(kitti, "ns-qr-sqrt-f64", 1, 0.02);
  const fs::path tables = writeTablesOf(SeedStats::kAuto);

  const Csv csv = readCsv(tables / "tables.csv", {"table", "row", "variant"});
  for (const auto& [key, values] : ate) {
    SCOPED_TRACE(key);
    const std::string k = "table1|" + key;
    EXPECT_DOUBLE_EQ(std::stod(csv.at(k, "ours")), mean(values));
    EXPECT_NEAR(std::stod(csv.at(k, "ours_std")), sampleStdOf(values), 1e-15);
    EXPECT_EQ(csv.at(k, "ours_state"), "ok");
  }
  EXPECT_EQ(csv.at("table1|" + room + "|ns-qr-sqrt-f32", "ours_failed"), "1");
  EXPECT_EQ(csv.at("table1|" + room + "|ns-qr-sqrt-f32", "n_runs"), "3");
  EXPECT_EQ(csv.at("table1|" + mh + "|ns-qr-sqrt-f64", "ours_failed"), "0");
  EXPECT_EQ(csv.at("table1|" + mh + "|sc-sc-sq-f32", "ours_state"), "failed");
  EXPECT_EQ(csv.at("table1|" + mh + "|sc-sc-sq-f32", "ours_failed"), "3");
  EXPECT_EQ(csv.at("table1|" + mh + "|sc-sc-sq-f64", "ours_state"), "missing");
  // The paper's single value beside (Table 1, MH03, √VIO-64: 0.051 in paper_values.toml).
  EXPECT_EQ(csv.at("table1|" + mh + "|ns-qr-sqrt-f64", "paper_state"), "ok");
  // Table 2 without seed statistics: no std, no failure count.
  EXPECT_DOUBLE_EQ(std::stod(csv.at("table2|" + kitti + "|ns-qr-sqrt-f64", "ours")), kitti_64);
  EXPECT_EQ(csv.at("table2|" + kitti + "|ns-qr-sqrt-f64", "ours_std"), "");
  EXPECT_EQ(csv.at("table2|" + kitti + "|ns-qr-sqrt-f64", "ours_failed"), "");

  // Markdown: mean ± std with the row's 4 decimals, and the failure counts.
  const std::string md = readText(tables / "table1.md");
  const std::vector<double>& room32 = ate.at(room + "|ns-qr-sqrt-f32");
  EXPECT_NE(md.find(fmt::format("{:.4f} ± {:.4f} x 1/3", mean(room32), sampleStdOf(room32))),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| x 3/3 |"), std::string::npos) << md;
  EXPECT_NE(md.find("Seeds: mean ± sample standard deviation"), std::string::npos) << md;
  EXPECT_NE(readText(tables / "table1.tex").find("$\\pm$"), std::string::npos);
  EXPECT_EQ(readText(tables / "table2.md").find(" ± "), std::string::npos);
  // No preconditioned storage among the runs: no preconditioned table.
  EXPECT_FALSE(fs::exists(tables / "preconditioned.md"));
}

// Issue #31 §3: the preconditioned storages beside the references that ran, whole sequences only,
// with seed statistics and the frames where the failed seeds stopped; no paper column.
TEST_F(SeedTables, PreconditionedTableHasTheNewStoragesBesideTheReferences) {
  const std::string mh = "euroc/MH_03_medium", kitti = "kitti/10";
  std::vector<double> sqp;
  for (int s = 1; s <= 3; ++s) {
    addRun(mh, "ns-qr-sqrt-f32", s, 1e-3 * s);
    if (s < 3) sqp.push_back(addRun(mh, "sc-sc-sqp-f32", s, 2e-3 * s));
  }
  addRun(mh, "sc-sc-sqp-f32", 3, 0.1, RunStatus::kFailed);  // stops at frame 19 (addRun)
  addRun(kitti, "sc-sc-sqrtp-f32", 1, 0.02);
  addRun(mh, "ns-sc-sqp-f32", 1, 0.01, RunStatus::kOk, "600");  // a short run: left out
  const fs::path tables = writeTablesOf(SeedStats::kAuto);

  const Csv csv = readCsv(tables / "preconditioned.csv", {"row", "variant"});
  EXPECT_DOUBLE_EQ(std::stod(csv.at(mh + "|sc-sc-sqp-f32", "ours")), mean(sqp));
  EXPECT_NEAR(std::stod(csv.at(mh + "|sc-sc-sqp-f32", "ours_std")), sampleStdOf(sqp), 1e-15);
  EXPECT_EQ(csv.at(mh + "|sc-sc-sqp-f32", "ours_failed"), "1");
  EXPECT_EQ(csv.at(kitti + "|sc-sc-sqrtp-f32", "ours_state"), "ok");
  EXPECT_EQ(csv.at(kitti + "|ns-qr-sqrt-f32", "ours_state"), "missing");
  EXPECT_EQ(csv.rows.count(mh + "|ns-sc-sqp-f32"), 0u);  // the short run's variant has no column
  EXPECT_EQ(csv.rows.count(mh + "|sc-sc-sq-f32"), 0u);   // a reference without runs neither

  const Csv failures = readCsv(tables / "preconditioned_failures.csv", {"row", "variant"});
  EXPECT_EQ(failures.at(mh + "|sc-sc-sqp-f32", "ours"), "19");
  EXPECT_EQ(failures.at(mh + "|ns-qr-sqrt-f32", "ours_state"), "missing");

  const std::string md = readText(tables / "preconditioned.md");
  EXPECT_NE(md.find("| sequence | frames | ns-qr-sqrt-f32 | sc-sc-sqp-f32 | sc-sc-sqrtp-f32 |"),
            std::string::npos)
      << md;
  EXPECT_EQ(md.find("paper |"), std::string::npos) << md;
  EXPECT_NE(md.find(fmt::format("{:.4f} ± {:.4f} x 1/3", mean(sqp), sampleStdOf(sqp))),
            std::string::npos)
      << md;
  const std::string tex = readText(tables / "preconditioned.tex");
  EXPECT_NE(tex.find("\\begin{tabular}{lrrrr}"), std::string::npos) << tex;
  EXPECT_EQ(tex.find("ours & paper"), std::string::npos);
}

TEST_F(SeedTables, ClaimTableComparesTheF32DifferenceWithTheF64Spread) {
  const std::string mh = "euroc/MH_03_medium", room = "tumvi/room1";
  std::map<std::string, std::map<int, double>> ate;  // dataset|bits → seed → ATE
  for (int s = 1; s <= 3; ++s) {
    ate[mh + "|64"][s] = addRun(mh, "ns-qr-sqrt-f64", s, 1e-3 * s);
    ate[mh + "|32"][s] = addRun(mh, "ns-qr-sqrt-f32", s, 1e-3 * s + 1e-5);
    ate[room + "|64"][s] = addRun(room, "ns-qr-sqrt-f64", s, 2e-3 + 1e-4 * s);
    ate[room + "|32"][s] = addRun(room, "ns-qr-sqrt-f32", s, 9e-3 * s);
  }
  const fs::path tables = writeTablesOf(SeedStats::kAuto);
  ASSERT_TRUE(fs::is_regular_file(tables / "seed_claim.md"));
  ASSERT_TRUE(fs::is_regular_file(tables / "seed_claim.tex"));
  const Csv csv = readCsv(tables / "seed_claim.csv", {"row"});
  for (const std::string& d : {mh, room}) {
    SCOPED_TRACE(d);
    std::vector<double> v64, v32, paired;
    for (const auto& [seed, x] : ate.at(d + "|64")) {
      v64.push_back(x);
      v32.push_back(ate.at(d + "|32").at(seed));
      paired.push_back(std::abs(ate.at(d + "|32").at(seed) - x));
    }
    const double delta = std::abs(mean(v32) - mean(v64));
    EXPECT_DOUBLE_EQ(std::stod(csv.at(d, "mean_f64")), mean(v64));
    EXPECT_NEAR(std::stod(csv.at(d, "std_f64")), sampleStdOf(v64), 1e-15);
    EXPECT_DOUBLE_EQ(std::stod(csv.at(d, "mean_f32")), mean(v32));
    EXPECT_NEAR(std::stod(csv.at(d, "delta")), delta, 1e-15);
    EXPECT_NEAR(std::stod(csv.at(d, "relative")), delta / mean(v64), 1e-12);
    EXPECT_NEAR(std::stod(csv.at(d, "paired")), mean(paired), 1e-15);
    EXPECT_EQ(csv.at(d, "seeds_f64"), "3");
    EXPECT_EQ(csv.at(d, "within"), delta <= sampleStdOf(v64) ? "yes" : "no");
  }
  // The constructed cases: √-f32 within the f64 spread on MH_03, far outside on room1.
  EXPECT_EQ(csv.at(mh, "within"), "yes");
  EXPECT_EQ(csv.at(room, "within"), "no");
}

TEST_F(SeedTables, OffKeepsSingleValuesAndOnWorksWithOneSeed) {
  const std::string mh = "euroc/MH_03_medium";
  std::vector<double> v;
  for (int s = 1; s <= 2; ++s) v.push_back(addRun(mh, "ns-qr-sqrt-f64", s, 1e-3 * s));
  addRun(mh, "ns-qr-sqrt-f32", 1, 1e-3);
  addRun(mh, "ns-qr-sqrt-f32", 2, 0.1, RunStatus::kFailed);
  const fs::path off = writeTablesOf(SeedStats::kOff);
  Csv csv = readCsv(off / "tables.csv", {"table", "row", "variant"});
  EXPECT_DOUBLE_EQ(std::stod(csv.at("table1|" + mh + "|ns-qr-sqrt-f64", "ours")), mean(v));
  EXPECT_EQ(csv.at("table1|" + mh + "|ns-qr-sqrt-f64", "ours_std"), "");
  // Without seed statistics any failed seed fails the cell, as before.
  EXPECT_EQ(csv.at("table1|" + mh + "|ns-qr-sqrt-f32", "ours_state"), "failed");
  EXPECT_FALSE(fs::exists(off / "seed_claim.md"));

  fs::remove_all(dir_ / "tables");
  const fs::path on = writeTablesOf(SeedStats::kOn);
  csv = readCsv(on / "tables.csv", {"table", "row", "variant"});
  EXPECT_EQ(csv.at("table1|" + mh + "|ns-qr-sqrt-f32", "ours_state"), "ok");
  EXPECT_EQ(csv.at("table1|" + mh + "|ns-qr-sqrt-f32", "ours_failed"), "1");
  // One ok seed: a mean without spread, and no verdict in the claim.
  EXPECT_EQ(csv.at("table1|" + mh + "|ns-qr-sqrt-f32", "ours_std"), "");
  const Csv claim = readCsv(on / "seed_claim.csv", {"row"});
  EXPECT_EQ(claim.at(mh, "within"), "no");  // √-f32 failed on a seed
  EXPECT_EQ(claim.at(mh, "failed_f32"), "1");
}

// A committed sweep folder holds index.csv without runs/: the tables from the index rows (whose
// summary the sweep copies from the results file) are the tables from the files, byte for byte.
TEST_F(SeedTables, AFolderWithoutItsResultsFilesGivesTheSameTablesFromItsIndex) {
  const std::string mh = "euroc/MH_03_medium", kitti = "kitti/10";
  for (int s = 1; s <= 3; ++s) {
    addRun(mh, "ns-qr-sqrt-f64", s, 1e-3 * s);
    addRun(mh, "ns-qr-sqrt-f32", s, 1e-3 * s + 1e-5);
    addRun(kitti, "sc-sc-sq-f32", s, 0.1, s == 2 ? RunStatus::kFailed : RunStatus::kOk);
  }
  for (IndexRow& row : rows_) {
    ASSERT_TRUE(detail::readCompleteResults((dir_ / "sweep" / row.get("results")).string(), &row));
  }
  const fs::path from_files = writeTablesOf(SeedStats::kAuto);
  fs::rename(from_files, dir_ / "from_files");
  fs::remove_all(dir_ / "sweep" / "runs");
  const ResultSet index_only = loadResults({(dir_ / "sweep").string()});
  ASSERT_EQ(index_only.warnings.size(), 1u);
  EXPECT_NE(index_only.warnings[0].find("9 run(s) read from index.csv"), std::string::npos)
      << index_only.warnings[0];
  const fs::path from_index = writeTablesOf(SeedStats::kAuto);
  int compared = 0;
  for (const auto& entry : fs::directory_iterator(dir_ / "from_files")) {
    SCOPED_TRACE(entry.path().filename().string());
    EXPECT_EQ(readText(from_index / entry.path().filename()), readText(entry.path()));
    ++compared;
  }
  EXPECT_GE(compared, 9);  // table1, table2 and the claim, each in md, tex and csv
  const Csv csv = readCsv(from_index / "tables.csv", {"table", "row", "variant"});
  EXPECT_EQ(csv.at("table2|" + kitti + "|sc-sc-sq-f32", "ours_failed"), "1");
}

// Without the summary columns (an index the sweep never completed) and without the file, an ok
// row is not a result.
TEST_F(SeedTables, AnOkRowWithoutFileOrSummaryIsCountedAsNotRun) {
  addRun("euroc/MH_03_medium", "ns-qr-sqrt-f64", 1, 1e-3);
  writeIndex((dir_ / "sweep" / "index.csv").string(), rows_);
  fs::remove_all(dir_ / "sweep" / "runs");
  const ResultSet set = loadResults({(dir_ / "sweep").string()});
  ASSERT_EQ(set.runs.size(), 1u);
  EXPECT_EQ(set.runs[0].state, RunRecord::State::kMissing);
  ASSERT_EQ(set.warnings.size(), 1u);
  EXPECT_NE(set.warnings[0].find("neither it nor its index row holds an ATE"), std::string::npos);
}

}  // namespace
}  // namespace marglab::experiment
