// `marglab sweep` / `tables` / `plot` end to end on short runs of the shipped KITTI sequences:
// the index and every table value agree with the HDF5 results files; a run killed with SIGKILL is
// recorded as failed without leaving a results file, and --resume redoes only it; the plotting
// script writes non-empty figures.

#include <gtest/gtest.h>

#include <fmt/core.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "common/cli_runner.h"
#include "core/experiment/sweep_index.h"
#include "core/io/results_file.h"
#include "test_paths.h"

namespace marglab::experiment {
namespace {

namespace fs = std::filesystem;
using test::quote;
using test::readText;
using test::runCli;
using test::startCli;

const IndexRow* findRow(const std::vector<IndexRow>& rows, const std::string& id) {
  for (const IndexRow& row : rows) {
    if (row.get("id") == id) return &row;
  }
  return nullptr;
}

// The cells of the Markdown / LaTeX table row that starts with `label`.
std::vector<std::string> tableRow(const std::string& text, const std::string& start, char sep) {
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(start, 0) != 0) continue;
    std::vector<std::string> cells;
    std::stringstream fields(line);
    for (std::string cell; std::getline(fields, cell, sep);) {
      const auto a = cell.find_first_not_of(' ');
      const auto b = cell.find_last_not_of(' ');
      cells.push_back(a == std::string::npos ? "" : cell.substr(a, b - a + 1));
    }
    return cells;
  }
  return {};
}

std::string stripBold(std::string cell) {
  for (const std::string& mark :
       {std::string("**"), std::string("\\textbf{"), std::string("}"), std::string(" \\\\")}) {
    for (auto p = cell.find(mark); p != std::string::npos; p = cell.find(mark)) {
      cell.erase(p, mark.size());
    }
  }
  return cell;
}

// One sweep shared by the tests of this suite: 4 headline variants on 30 frames of KITTI 10,
// three variants × two seeds on KITTI 04, and one KITTI 04 run with a NaN injected at frame 12
// (a numerical failure: complete results file, status failed).
class SweepEndToEnd : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("marglab_sweep_e2e_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(dir_ / "e2e.toml") << R"(name = "e2e"
[[group]]
name = "vo"
datasets = ["kitti/10"]
variants = ["headline"]
frames = 30
[[group]]
name = "k04"
datasets = ["kitti/04"]
variants = ["ns-qr-sqrt-f64", "sc-sc-sq-f64", "sc-sc-sq-f32"]
seeds = [1, 2]
frames = 20
[[group]]
name = "nan"
datasets = ["kitti/04"]
variants = ["ns-qr-sqrt-f32"]
frames = 30
args = ["--inject-nan-frame", "12"]
)";
    sweep_ = runCli("sweep " + quote(dir_ / "e2e.toml") + " --jobs 2 --out " + quote(out()));
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static fs::path out() { return dir_ / "out"; }

  static fs::path dir_;
  static test::CliResult sweep_;
};
fs::path SweepEndToEnd::dir_;
test::CliResult SweepEndToEnd::sweep_;

TEST_F(SweepEndToEnd, IndexListsEveryRunWithTheValuesOfItsResultsFile) {
  // A numerical failure is a result, not a crash: the sweep succeeds.
  ASSERT_EQ(sweep_.exit_code, 0) << sweep_.output;
  EXPECT_NE(sweep_.output.find("10 ok, 1 failed numerically, 0 crashed"), std::string::npos)
      << sweep_.output;
  const auto rows = readIndex((out() / "index.csv").string());
  ASSERT_EQ(rows.size(), 11u);
  for (const IndexRow& row : rows) {
    SCOPED_TRACE(row.get("id"));
    const ResultsReader reader((out() / row.get("results")).string());
    EXPECT_EQ(reader.info().metadata.variant, row.get("variant"));
    EXPECT_EQ(std::to_string(reader.info().metadata.seed), row.get("seed"));
    EXPECT_EQ(reader.info().status, row.get("status"));
    const SummaryValues s = reader.summary();
    EXPECT_EQ(row.number("ate_rmse"), s.ate_rmse);
    EXPECT_EQ(row.number("t_opt_total_s"), s.t_opt_total_s);
    EXPECT_EQ(row.number("n_frames"), static_cast<double>(s.n_frames));
    EXPECT_TRUE(fs::file_size(out() / row.get("log")) > 0);
    EXPECT_EQ(row.get("exit_code"), row.get("status") == "ok" ? "0" : "1");
  }
  const IndexRow* nan = findRow(rows, "nan__kitti-04__ns-qr-sqrt-f32__s1");
  ASSERT_NE(nan, nullptr);
  EXPECT_EQ(nan->get("status"), "failed");
  EXPECT_EQ(nan->get("failure_kind"), "numerical");
  EXPECT_EQ(nan->get("failure_frame"), "12");
  // The command column repeats the run from the sweep folder.
  EXPECT_NE(nan->get("command").find("--inject-nan-frame 12"), std::string::npos);
}

// Independent expectation: mean over seeds of the HDF5 /summary values, per dataset × variant
// ("dataset|variant").
struct RunMeans {
  std::map<std::string, std::vector<SummaryValues>> runs;
  std::map<std::string, bool> failed;

  bool failedAny(const std::string& key) const { return failed.count(key) && failed.at(key); }
  double mean(const std::string& key, double SummaryValues::*field) const {
    double sum = 0;
    for (const SummaryValues& s : runs.at(key)) sum += s.*field;
    return sum / static_cast<double>(runs.at(key).size());
  }
};

RunMeans runMeans(const fs::path& out) {
  RunMeans m;
  for (const IndexRow& row : readIndex((out / "index.csv").string())) {
    const ResultsReader reader((out / row.get("results")).string());
    const std::string key = row.get("dataset") + "|" + row.get("variant");
    m.runs[key].push_back(reader.summary());
    m.failed[key] = m.failed[key] || reader.info().status == "failed";
  }
  return m;
}

// Every cell of the CSV (full precision) against the means; returns the cells checked.
int checkCsvCells(const fs::path& file, const RunMeans& m) {
  const auto csv = parseCsv(readText(file), file.filename().string());
  EXPECT_GT(csv.size(), 1u);
  if (csv.empty()) return 0;
  const auto& header = csv.front();
  auto col = [&](const char* name) {
    return static_cast<std::size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  int checked = 0;
  for (std::size_t r = 1; r < csv.size(); ++r) {
    const auto& f = csv[r];
    const std::string key = f[col("row")] + "|" + f[col("variant")];
    if (!m.runs.count(key)) {
      EXPECT_EQ(f[col("ours_state")], "missing") << key;
      continue;
    }
    SCOPED_TRACE(f[col("table")] + " " + key + " " + f[col("quantity")]);
    if (m.failedAny(key)) {
      EXPECT_EQ(f[col("ours_state")], "failed");
      EXPECT_EQ(f[col("ours")], "");
      continue;
    }
    EXPECT_EQ(f[col("ours_state")], "ok");
    const std::string q = f[col("quantity")];
    const double want = q == "ate"   ? m.mean(key, &SummaryValues::ate_rmse)
                        : q == "opt" ? m.mean(key, &SummaryValues::t_opt_total_s)
                                     : m.mean(key, &SummaryValues::t_marg_total_s);
    EXPECT_DOUBLE_EQ(std::stod(f[col("ours")]), want);
    EXPECT_EQ(f[col("n_runs")], std::to_string(m.runs.at(key).size()));
    ++checked;
  }
  return checked;
}

// The printed ATE (4 decimals) of every cell of Table 2 in Markdown and LaTeX.
void checkTable2Cells(const std::string& md, const std::string& tex, const RunMeans& m) {
  const std::vector<std::string> variants = {"ns-qr-sqrt-f64", "ns-qr-sqrt-f32", "sc-sc-sq-f64",
                                             "sc-sc-sq-f32"};
  for (const auto& [dataset, label] : std::vector<std::pair<std::string, std::string>>{
           {"kitti/10", "kitti10"}, {"kitti/04", "kitti04"}}) {
    const auto md_cells = tableRow(md, "| " + label + " |", '|');
    const auto tex_cells = tableRow(tex, label + " &", '&');
    ASSERT_EQ(md_cells.size(), 1u + 2u + 8u) << md;  // leading empty, label, frames, 4×2
    ASSERT_EQ(tex_cells.size(), 2u + 8u) << tex;     // label, frames, 4×2
    for (std::size_t v = 0; v < variants.size(); ++v) {
      const std::string key = dataset + "|" + variants[v];
      const std::string want = !m.runs.count(key) ? "–"
                               : m.failedAny(key)
                                   ? "x"
                                   : fmt::format("{:.4f}", m.mean(key, &SummaryValues::ate_rmse));
      EXPECT_EQ(stripBold(md_cells[3 + 2 * v]), want) << key;
      EXPECT_EQ(stripBold(tex_cells[2 + 2 * v]), want == "–" ? "--" : want) << key;
    }
  }
}

TEST_F(SweepEndToEnd, TablesInThreeFormatsEqualTheHdf5Values) {
  ASSERT_EQ(sweep_.exit_code, 0) << sweep_.output;
  // kitti/04 has two seeds: --seeds off keeps the single-value cells checked here (mean over
  // seeds, `x` when any failed); the seed statistics are checked in test_seed_tables.cpp.
  const auto result = runCli("tables " + quote(out()) + " --format md,tex,csv --seeds off");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const fs::path tables = out() / "tables";
  for (const char* name : {"tables.md", "tables.tex", "tables.csv", "table2.md", "table2.tex",
                           "table2.csv", "table5.md", "table5.tex", "table5.csv"}) {
    EXPECT_TRUE(fs::is_regular_file(tables / name)) << name;
  }
  const RunMeans means = runMeans(out());
  EXPECT_EQ(checkCsvCells(tables / "tables.csv", means), 7 + 7 * 2);  // Table 2: 7 ok cells (one
                                                                      // failed); Table 5: 7 × 2
  // Markdown and LaTeX: the printed value of every cell of Table 2 (4 decimals).
  const std::string md = readText(tables / "table2.md");
  checkTable2Cells(md, readText(tables / "table2.tex"), means);
  // The paper's whole-sequence value (Table 2, kitti10, VO-32 = 26.12) never beside 30 frames.
  EXPECT_EQ(tableRow(md, "| kitti10 |", '|').back(), "–");
  EXPECT_EQ(md.find("26.12"), std::string::npos) << md;
}

TEST_F(SweepEndToEnd, PlotScriptWritesNonEmptyFigures) {
  ASSERT_EQ(sweep_.exit_code, 0) << sweep_.output;
  const fs::path figures = dir_ / "figures";
  const auto result =
      runCli("plot " + quote(out()) + " --vo-dataset kitti/10 --out " + quote(figures));
  if (result.output.find("no Python with matplotlib") != std::string::npos) {
    GTEST_SKIP() << "no Python with matplotlib, h5py and numpy: " << result.output;
  }
  ASSERT_EQ(result.exit_code, 0) << result.output;
  for (const char* name :
       {"fig5_dEm_kitti-10", "fig6_sigma_min_kitti-10", "fig7_trajectory_kitti-10"}) {
    for (const char* ext : {".png", ".pdf"}) {
      const fs::path file = figures / (std::string(name) + ext);
      ASSERT_TRUE(fs::is_regular_file(file)) << file << "\n" << result.output;
      EXPECT_GT(fs::file_size(file), 5000u) << file;
    }
  }
  // PNG signature.
  EXPECT_EQ(readText(figures / "fig6_sigma_min_kitti-10.png").substr(1, 3), "PNG");
}

struct FileStamp {
  ino_t inode;
  std::int64_t mtime_ns;
  bool operator==(const FileStamp& o) const { return inode == o.inode && mtime_ns == o.mtime_ns; }
};
FileStamp stamp(const fs::path& path) {
  struct stat st {};
  EXPECT_EQ(stat(path.c_str(), &st), 0) << path;
  return {st.st_ino,
          static_cast<std::int64_t>(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec};
}

// The pid of run `id` once the sweep's index says it is running; 0 when it does not within 60 s.
pid_t runningChild(const fs::path& out, const std::string& id) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    try {
      const auto rows = readIndex((out / "index.csv").string());
      const IndexRow* row = findRow(rows, id);
      if (row != nullptr && row->get("status") == "running" && !row->get("pid").empty()) {
        return static_cast<pid_t>(std::stol(row->get("pid")));
      }
    } catch (const std::exception&) {
      // The sweep has not written its index yet.
    }
  }
  return 0;
}

// A damaged results file (not a complete HDF5 file) is redone by --resume, the others kept; and
// without --resume an existing sweep folder is not overwritten.
void expectDamagedRedoneAndNoClobber(const fs::path& sweep_file, const fs::path& out,
                                     const fs::path& damaged, const std::string& damaged_id) {
  fs::resize_file(damaged, fs::file_size(damaged) / 2);
  const auto again =
      runCli("sweep " + quote(sweep_file) + " --jobs 1 --resume --out " + quote(out));
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find("[1/1] ok"), std::string::npos) << again.output;
  EXPECT_NE(again.output.find(damaged_id), std::string::npos) << again.output;
  EXPECT_NE(again.output.find("(2 kept"), std::string::npos) << again.output;
  EXPECT_EQ(ResultsReader(damaged.string()).info().status, "ok");

  const auto clobber = runCli("sweep " + quote(sweep_file) + " --out " + quote(out));
  EXPECT_EQ(clobber.exit_code, 2) << clobber.output;
  EXPECT_NE(clobber.output.find("--resume"), std::string::npos) << clobber.output;
}

TEST(SweepKill, KilledRunIsFailedAndResumeRedoesOnlyIt) {
  const fs::path dir =
      fs::temp_directory_path() / ("marglab_sweep_kill_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "kill.toml") << R"(name = "kill"
[[group]]
name = "long"
datasets = ["kitti/10"]
variants = ["ns-qr-sqrt-f64"]
frames = 250
[[group]]
name = "short"
datasets = ["kitti/04"]
variants = ["ns-qr-sqrt-f32", "sc-sc-sq-f64"]
frames = 20
)";
  const fs::path out = dir / "out";
  const std::string long_id = "long__kitti-10__ns-qr-sqrt-f64__s1";
  const std::vector<std::string> short_ids = {"short__kitti-04__ns-qr-sqrt-f32__s1",
                                              "short__kitti-04__sc-sc-sq-f64__s1"};
  // One job: the longest run starts first and the short ones wait for it.
  const pid_t sweep =
      startCli({"sweep", (dir / "kill.toml").string(), "--jobs", "1", "--out", out.string()},
               dir / "sweep.log");
  ASSERT_GT(sweep, 0);
  const pid_t child = runningChild(out, long_id);
  ASSERT_NE(child, 0) << readText(dir / "sweep.log");
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // mid-way through its frames
  ASSERT_EQ(kill(child, SIGKILL), 0);
  int status = 0;
  ASSERT_EQ(waitpid(sweep, &status, 0), sweep);
  const std::string log = readText(dir / "sweep.log");
  ASSERT_TRUE(WIFEXITED(status)) << log;
  EXPECT_EQ(WEXITSTATUS(status), 1) << log;  // a crashed run makes the sweep fail …

  auto rows = readIndex((out / "index.csv").string());
  const IndexRow* killed = findRow(rows, long_id);
  ASSERT_NE(killed, nullptr);
  EXPECT_EQ(killed->get("status"), "failed");
  EXPECT_EQ(killed->get("failure_kind"), "signal");
  EXPECT_EQ(killed->get("signal"), std::to_string(SIGKILL));
  EXPECT_NE(killed->get("reason").find("SIGKILL"), std::string::npos) << killed->get("reason");
  // … never a half-written results file, nor a leftover temporary.
  EXPECT_FALSE(fs::exists(out / killed->get("results")));
  for (const auto& entry : fs::directory_iterator(out / "runs")) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos) << entry.path();
  }
  std::map<std::string, FileStamp> before;
  for (const std::string& id : short_ids) {
    const IndexRow* row = findRow(rows, id);
    ASSERT_NE(row, nullptr);
    EXPECT_EQ(row->get("status"), "ok") << id;  // … while the sweep went on
    before[id] = stamp(out / row->get("results"));
  }

  const auto resume =
      runCli("sweep " + quote(dir / "kill.toml") + " --jobs 1 --resume --out " + quote(out));
  ASSERT_EQ(resume.exit_code, 0) << resume.output;
  EXPECT_NE(resume.output.find("[1/1] ok"), std::string::npos) << resume.output;
  EXPECT_NE(resume.output.find("(2 kept from an earlier invocation)"), std::string::npos)
      << resume.output;
  rows = readIndex((out / "index.csv").string());
  EXPECT_EQ(findRow(rows, long_id)->get("status"), "ok");
  EXPECT_EQ(findRow(rows, long_id)->get("reused"), "");
  const ResultsReader redone((out / findRow(rows, long_id)->get("results")).string());
  EXPECT_EQ(redone.info().status, "ok");
  EXPECT_EQ(redone.summary().n_frames, 250);
  for (const std::string& id : short_ids) {
    EXPECT_EQ(findRow(rows, id)->get("reused"), "1") << id;
    EXPECT_TRUE(stamp(out / findRow(rows, id)->get("results")) == before[id]) << id;
  }

  expectDamagedRedoneAndNoClobber(dir / "kill.toml", out,
                                  out / findRow(rows, short_ids[0])->get("results"), short_ids[0]);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace marglab::experiment
