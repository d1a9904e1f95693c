// The marginalization-strategy tables (sparsify_table1 / sparsify_table2, Hsiung et al. Tables I
// and II) from synthetic results files of two strategies: every value of ours equals the one
// computed here from what was written, the paper's values sit beside the nfr and discard columns,
// a failed run is `x`, and folders without dense / nfr runs produce no strategy table; the Fig. 6
// analogs are drawn from the same files.

#include <gtest/gtest.h>

#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/common/statistics.h"
#include "core/experiment/sweep_index.h"
#include "core/experiment/tables.h"
#include "core/io/results_file.h"

namespace marglab::experiment {
namespace {

namespace fs = std::filesystem;
using test::readText;

constexpr int kFrames = 24;
constexpr int kMaxKfs = 3;

// What the tables must show for one run, computed from the values written.
struct Expected {
  double ate = 0, kld = 0, nnz_ratio = 0;
  std::vector<double> t_opt, t_marg_kf;  // per frame; per keyframe marginalization
};

double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}
double rmseOf(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return std::sqrt(s / static_cast<double>(v.size()));
}
double stdOf(const std::vector<double>& v) {
  const double m = mean(v);
  double s = 0;
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / static_cast<double>(v.size()));
}

// A run of `strategy` on `dataset`: keyframes at even frames; nfr runs have a /sparsify row at
// every keyframe from the (kMaxKfs + 1)-th on, every third of them kept dense (KLD NaN).
Expected writeRun(const std::string& path, const std::string& dataset, const std::string& strategy,
                  int salt, RunStatus status) {
  RunMetadata m;
  m.dataset = "euroc";
  m.sequence = dataset.substr(dataset.find('/') + 1);
  m.variant = "ns-qr-sqrt-f64";
  m.precision = "f64";
  m.mode = "vio";
  m.seed = 1;
  m.config_toml = fmt::format("[window]\nmax_kfs = {}\nmax_states = 3\n", kMaxKfs);
  m.marg_strategy = strategy;
  ResultsWriter w = ResultsWriter::create(path, m);
  Expected e;
  int keyframes = 0, events = 0;
  std::vector<double> kld, ratio;
  for (int i = 0; i < kFrames; ++i) {
    FrameRecord f;
    f.t_ns = 1'000'000'000LL + i * 50'000'000LL;
    f.is_keyframe = i % 2 == 0;
    f.t_opt_s = 0.01 + 1e-3 * ((i * 7 + salt) % 5);
    f.t_marg_s = 0.002 + 1e-3 * ((i * 3 + salt) % 4);
    f.p_gt = Eigen::Vector3d(0.1 * i, std::sin(0.2 * i), 0.05 * i * i);
    f.p_est = f.p_gt + 1e-3 * (1 + salt) * Eigen::Vector3d(std::cos(i), std::sin(3 * i), 0.3);
    w.appendFrame(f);
    e.t_opt.push_back(f.t_opt_s);
    if (!f.is_keyframe || ++keyframes <= kMaxKfs) continue;
    e.t_marg_kf.push_back(f.t_marg_s);
    if (strategy == "discard") continue;
    SparsifyRecord s;
    s.frame_index = i;
    s.t_ns = f.t_ns;
    s.blanket_cols = 15 + 3 * i;
    s.n_blanket_poses = 1;
    s.n_blanket_landmarks = i;
    s.nnz_dense = static_cast<std::int64_t>(s.blanket_cols) * s.blanket_cols;
    s.recovered = strategy == "nfr" && events % 3 != 2;
    s.nnz_sparse = s.recovered ? s.nnz_dense / 2 + i : s.nnz_dense;
    s.kld = s.recovered ? 0.01 * (i + salt) : std::numeric_limits<double>::quiet_NaN();
    s.t_schur_s = 1e-3;
    s.t_recovery_s = 2e-3;
    w.appendSparsify(s);
    ++events;
    if (s.recovered) kld.push_back(s.kld);
    ratio.push_back(static_cast<double>(s.nnz_sparse) / static_cast<double>(s.nnz_dense));
  }
  e.kld = kld.empty() ? 0 : mean(kld);
  e.nnz_ratio = ratio.empty() ? 0 : mean(ratio);
  e.ate =
      w.finish(RunSummary{}, status, status == RunStatus::kOk ? -1 : kFrames - 1, "test").ate_rmse;
  return e;
}

class StrategyTables : public test::TempDirTest {
 protected:
  void SetUp() override { fs::create_directories(dir_ / "sweep" / "runs"); }

  // Writes the run and its index row (the strategy is also the override, as in
  // experiments/sparsify_euroc.toml).
  void addRun(const std::string& dataset, const std::string& strategy, int salt,
              RunStatus status = RunStatus::kOk) {
    const std::string id = fmt::format("euroc__{}__ns-qr-sqrt-f64__s1__{}",
                                       dataset.substr(dataset.find('/') + 1), strategy);
    const std::string results = "runs/" + id + ".h5";
    expected_[dataset + ":" + strategy] =
        writeRun((dir_ / "sweep" / results).string(), dataset, strategy, salt, status);
    IndexRow row;
    row.set("id", id);
    row.set("group", "euroc");
    row.set("dataset", dataset);
    row.set("variant", "ns-qr-sqrt-f64");
    row.set("seed", "1");
    row.set("frames", "0");
    row.set("override", strategy);
    row.set("status", status == RunStatus::kOk ? "ok" : "failed");
    row.set("results", results);
    rows_.push_back(row);
  }

  fs::path writeIndexFile() {
    writeIndex((dir_ / "sweep" / "index.csv").string(), rows_);
    return dir_ / "sweep";
  }

  fs::path writeTablesOf() {
    writeIndexFile();
    TablesRequest request;
    request.dirs = {(dir_ / "sweep").string()};
    request.out = (dir_ / "tables").string();
    writeTables(request, nullptr);
    return dir_ / "tables";
  }

  std::vector<IndexRow> rows_;
  std::map<std::string, Expected> expected_;  // dataset:strategy
};

// The cells of a tables.csv, keyed "table|row|variant|quantity".
class CsvCells {
 public:
  explicit CsvCells(const std::vector<std::vector<std::string>>& csv) : header_(csv.front()) {
    for (std::size_t r = 1; r < csv.size(); ++r) {
      const auto& f = csv[r];
      cells_[f[col("table")] + "|" + f[col("row")] + "|" + f[col("variant")] + "|" +
             f[col("quantity")]] = f;
    }
  }
  std::size_t col(const char* name) const {
    return static_cast<std::size_t>(std::find(header_.begin(), header_.end(), name) -
                                    header_.begin());
  }
  // The CSV row of a cell (a test failure and empty fields when there is none).
  const std::vector<std::string>& cell(const std::string& key) const {
    const auto it = cells_.find(key);
    EXPECT_NE(it, cells_.end()) << key;
    return it == cells_.end() ? none_ : it->second;
  }
  // Our value of a cell that must be ok.
  double number(const std::string& key) const {
    const auto& f = cell(key);
    EXPECT_EQ(f[col("ours_state")], "ok") << key;
    return f[col("ours")].empty() ? std::nan("") : std::stod(f[col("ours")]);
  }

 private:
  std::vector<std::string> header_;
  std::map<std::string, std::vector<std::string>> cells_;
  std::vector<std::string> none_ = std::vector<std::string>(header_.size());
};

// The trimmed cells of the Markdown table line that starts with `prefix`.
std::vector<std::string> markdownCells(const std::string& md, const std::string& prefix) {
  std::istringstream lines(md);
  std::vector<std::string> printed;
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind(prefix, 0) != 0) continue;
    std::stringstream fields(line);
    for (std::string f; std::getline(fields, f, '|');) {
      const auto a = f.find_first_not_of(' '), b = f.find_last_not_of(' ');
      if (a != std::string::npos) printed.push_back(f.substr(a, b - a + 1));
    }
  }
  return printed;
}

TEST_F(StrategyTables, ValuesEqualTheResultsFiles) {
  addRun("euroc/MH_02_easy", "nfr", 0);
  addRun("euroc/MH_02_easy", "discard", 1);
  addRun("euroc/V1_02_medium", "nfr", 2);
  addRun("euroc/V1_02_medium", "discard", 3, RunStatus::kFailed);
  const fs::path tables = writeTablesOf();
  for (const char* name : {"sparsify_table1", "sparsify_table2"}) {
    for (const char* ext : {".md", ".tex", ".csv"}) {
      EXPECT_TRUE(fs::is_regular_file(tables / (std::string(name) + ext))) << name << ext;
    }
  }

  const auto csv = parseCsv(readText(tables / "tables.csv"), "tables.csv");
  ASSERT_GT(csv.size(), 1u);
  const CsvCells cells(csv);
  auto col = [&](const char* name) { return cells.col(name); };
  auto cell = [&](const std::string& key) -> const std::vector<std::string>& {
    return cells.cell(key);
  };
  auto number = [&](const std::string& key) { return cells.number(key); };

  // Table I analog.
  for (const std::string d : {"euroc/MH_02_easy", "euroc/V1_02_medium"}) {
    SCOPED_TRACE(d);
    const Expected& nfr = expected_.at(d + ":nfr");
    EXPECT_DOUBLE_EQ(number("sparsify_table1|" + d + "|nfr|ate"), nfr.ate);
    EXPECT_DOUBLE_EQ(number("sparsify_table1|" + d + "|nfr|kld"), nfr.kld);
    EXPECT_DOUBLE_EQ(number("sparsify_table1|" + d + "|nfr|nnz_ratio"), nfr.nnz_ratio);
    EXPECT_EQ(cell("sparsify_table1|" + d + "|dense|ate")[col("ours_state")], "missing");
  }
  EXPECT_DOUBLE_EQ(number("sparsify_table1|euroc/MH_02_easy|discard|ate"),
                   expected_.at("euroc/MH_02_easy:discard").ate);
  EXPECT_EQ(cell("sparsify_table1|euroc/V1_02_medium|discard|ate")[col("ours_state")], "failed");
  // The paper's Proposed and OKVIS (ours) beside nfr and discard.
  EXPECT_EQ(cell("sparsify_table1|euroc/MH_02_easy|nfr|ate")[col("paper")], "0.059999999999999998");
  EXPECT_EQ(cell("sparsify_table1|euroc/MH_02_easy|discard|ate")[col("paper")],
            "0.14399999999999999");
  EXPECT_EQ(cell("sparsify_table1|euroc/MH_02_easy|nfr|kld")[col("paper_state")], "missing");

  // Table II analog.
  for (const std::string key :
       {"euroc/MH_02_easy:nfr", "euroc/MH_02_easy:discard", "euroc/V1_02_medium:nfr"}) {
    SCOPED_TRACE(key);
    const Expected& e = expected_.at(key);
    const std::string prefix = "sparsify_table2|" + key + "|";
    EXPECT_DOUBLE_EQ(number(prefix + "opt_mean|time_s"), mean(e.t_opt));
    EXPECT_DOUBLE_EQ(number(prefix + "opt_rmse|time_s"), rmseOf(e.t_opt));
    EXPECT_NEAR(number(prefix + "opt_std|time_s"), stdOf(e.t_opt), 1e-15);
    EXPECT_DOUBLE_EQ(number(prefix + "marg_mean|time_s"), mean(e.t_marg_kf));
    EXPECT_DOUBLE_EQ(number(prefix + "marg_rmse|time_s"), rmseOf(e.t_marg_kf));
    EXPECT_NEAR(number(prefix + "marg_std|time_s"), stdOf(e.t_marg_kf), 1e-15);
  }
  EXPECT_EQ(cell("sparsify_table2|euroc/V1_02_medium:discard|opt_mean|time_s")[col("ours_state")],
            "failed");
  EXPECT_EQ(cell("sparsify_table2|euroc/MH_02_easy:nfr|opt_mean|time_s")[col("paper")],
            "0.042999999999999997");
  EXPECT_EQ(cell("sparsify_table2|euroc/MH_02_easy:discard|opt_mean|time_s")[col("paper_state")],
            "missing");

  // Markdown: the printed cells of MH_02_easy in Table I (ATE of nfr, dense, discard, then KLD and
  // nnz ratio, each with the paper's beside), bold only among the ATE columns.
  const std::string md = readText(tables / "sparsify_table1.md");
  const std::vector<std::string> printed = markdownCells(md, "| MH_02_easy |");
  const Expected& nfr = expected_.at("euroc/MH_02_easy:nfr");
  const Expected& discard = expected_.at("euroc/MH_02_easy:discard");
  const bool nfr_best = std::round(nfr.ate * 1e4) <= std::round(discard.ate * 1e4);
  auto bold = [](bool b, const std::string& text) { return b ? "**" + text + "**" : text; };
  EXPECT_EQ(printed,
            (std::vector<std::string>{
                "MH_02_easy", "all", bold(nfr_best, fmt::format("{:.4f}", nfr.ate)), "**0.060**",
                "–", "–", bold(!nfr_best, fmt::format("{:.4f}", discard.ate)), "0.144",
                fmt::format("{:.3f}", nfr.kld), "–", fmt::format("{:.3f}", nfr.nnz_ratio), "–"}))
      << md;
}

TEST_F(StrategyTables, PlotDrawsTheFig6AnalogsOfNfrRuns) {
  addRun("euroc/MH_02_easy", "nfr", 0);
  addRun("euroc/V1_02_medium", "nfr", 2);
  addRun("euroc/V1_02_medium", "discard", 3);
  const fs::path sweep = writeIndexFile();
  const auto result = test::runCli("plot '" + sweep.string() + "' --figure sparsify --out '" +
                                   (dir_ / "figures").string() + "'");
  if (result.output.find("no Python with matplotlib") != std::string::npos) {
    GTEST_SKIP() << "no Python with matplotlib, h5py and numpy: " << result.output;
  }
  ASSERT_EQ(result.exit_code, 0) << result.output;
  for (const char* name : {"sparsify_fig6a", "sparsify_fig6b", "sparsify_kld"}) {
    for (const char* ext : {".png", ".pdf"}) {
      const fs::path file = dir_ / "figures" / (std::string(name) + ext);
      ASSERT_TRUE(fs::is_regular_file(file)) << file << "\n" << result.output;
      EXPECT_GT(fs::file_size(file), 5000u) << file;
    }
  }
}

TEST_F(StrategyTables, NoStrategyTablesWithoutDenseOrNfrRuns) {
  addRun("euroc/MH_02_easy", "discard", 1);
  const fs::path tables = writeTablesOf();
  EXPECT_FALSE(fs::exists(tables / "sparsify_table1.md"));
  EXPECT_FALSE(fs::exists(tables / "sparsify_table2.md"));
  EXPECT_TRUE(fs::is_regular_file(tables / "table1__discard.md"));
}

}  // namespace
}  // namespace marglab::experiment
