// Issue #20, on a tiny sweep generated here (KITTI 10 √VO-64/√VO-32 and EuRoC MH_01 VIO-64/VIO-32,
// a few dozen frames each; VIO-32 fails at its first marginalizations):
//   - `marglab tables` (tables.cpp), the Python reader (tools/scripts/marglab_results.py) and the
//     independent checker (check_results.py) agree on every run (test/cli/readers_agree.py);
//   - `marglab notebooks` executes the three notebooks (one per run, the sweep, f32 vs f64);
//   - `marglab report --check` writes report.html and opens it in headless Chromium: screenshot,
//     no console errors, its tables and figures present; a broken page is caught.
// Skipped, with the Debian packages to install, when Python's Jupyter / pandas or Chromium are
// missing.

#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>
#include <vector>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "common/cli_runner.h"
#include "core/common/source_dir.h"
#include "test_paths.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::runCli;
using test::runShell;

std::string pythonWith(const std::string& modules) {
  for (const std::string candidate : {"/usr/bin/python3", "python3"}) {
    if (std::system((candidate + " -c 'import " + modules + "' > /dev/null 2>&1").c_str()) == 0) {
      return candidate;
    }
  }
  return {};
}

bool haveChromium() {
  return std::system("command -v chromium > /dev/null 2>&1") == 0 ||
         std::system("command -v chromium-browser > /dev/null 2>&1") == 0;
}

std::string readFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class AnalysisTest : public ::testing::Test {
 protected:
  void SetUp() override {
    python_ = pythonWith("h5py, numpy, pandas");
    if (python_.empty()) {
      GTEST_SKIP() << "no python3 with h5py, numpy and pandas: install the Debian packages "
                      "python3-h5py python3-numpy python3-pandas";
    }
    dir_ = fs::path(test::binaryDir()) / "test_analysis" /
           ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(dir_ / "tiny.toml") << R"(name = "tiny"
description = "test_analysis: two short VO and two short VIO runs"
[[group]]
name = "vo"
datasets = ["kitti/10"]
variants = ["ns-qr-sqrt-f64", "ns-qr-sqrt-f32"]
frames = 40
[[group]]
name = "vio"
datasets = ["euroc/MH_01_easy"]
variants = ["sc-sc-sq-f64", "sc-sc-sq-f32"]
frames = 40
args = ["--isa", "sse2"]
)";
    // --isa sse2: the report is checked for VIO-32's failure frame ("failed @ 9"), which depends
    // on the kernels' ISA by a frame or two (results/perf/isa.md).
    sweep_ = (dir_ / "tiny").string();
    const auto sweep =
        runCli("sweep '" + (dir_ / "tiny.toml").string() + "' --jobs 2 --out '" + sweep_ + "'");
    // VIO-32 fails numerically (a result, not an error); the sweep itself must complete.
    ASSERT_TRUE(fs::is_regular_file(fs::path(sweep_) / "index.csv")) << sweep.output;
    const auto tables = runCli("tables '" + sweep_ + "'");
    ASSERT_EQ(tables.exit_code, 0) << tables.output;
    ASSERT_TRUE(fs::is_regular_file(fs::path(sweep_) / "tables" / "tables.csv"));
  }

  std::string python_;
  fs::path dir_;
  std::string sweep_;
};

TEST_F(AnalysisTest, TablesPythonReaderAndCheckResultsAgreeOnEveryRun) {
  const auto agree =
      runShell(python_ + " '" + sourceDir() + "/test/cli/readers_agree.py' '" + sweep_ + "'");
  EXPECT_EQ(agree.exit_code, 0) << agree.output;
  EXPECT_NE(agree.output.find("AGREE 4 runs"), std::string::npos) << agree.output;
}

// schema_version 2: the optional /frontend group (per-frame counts and time) and the root
// attribute `frontend`; both readers accept it, and check_results.py rejects a wrong shape.
TEST_F(AnalysisTest, FrontendGroupOfSchemaVersion2) {
  const std::string run =
      (fs::path(sweep_) / "runs" / "vo__kitti-10__ns-qr-sqrt-f64__s1.h5").string();
  const std::string v2 = (dir_ / "v2.h5").string();
  fs::copy_file(run, v2);
  const std::string scripts = std::string(sourceDir()) + "/tools/scripts";
  const auto add =
      runShell(python_ + " -c \"import h5py, numpy as np; f = h5py.File('" + v2 +
               "', 'r+'); n = f['frames/t_ns'].shape[0]; f.attrs['schema_version'] = 2; "
               "f.attrs['frontend'] = 'tracks'; del f['frontend']; g = f.create_group('frontend'); "
               "g['t_ns'] = f['frames/t_ns'][:]; g['n_tracked'] = np.arange(n, dtype=np.int64); "
               "g['n_new'] = np.ones(n, dtype=np.int64); g['n_features'] = np.arange(n) + 1; "
               "g['n_stereo'] = np.arange(n, dtype=np.int64); "
               "g['t_frontend_s'] = np.full(n, 1e-3); f.close()\"");
  ASSERT_EQ(add.exit_code, 0) << add.output;
  const auto check = runShell(python_ + " '" + scripts + "/check_results.py' '" + v2 + "'");
  EXPECT_EQ(check.exit_code, 0) << check.output;
  EXPECT_NE(check.output.find("schema_version 2"), std::string::npos) << check.output;
  const auto read = runShell(python_ + " -c \"import sys; sys.path.insert(0, '" + scripts +
                             "'); import marglab_results as mr; r = mr.read_run('" + v2 +
                             "'); print(r.attrs['frontend'], r.frontend.shape[0] == len(r.frames), "
                             "list(r.frontend.columns))\"");
  EXPECT_EQ(read.exit_code, 0) << read.output;
  EXPECT_NE(read.output.find("tracks True ['t_ns', 'n_features', 'n_tracked', 'n_new', "
                             "'n_stereo', 't_frontend_s']"),
            std::string::npos)
      << read.output;
  const auto cut = runShell(python_ + " -c \"import h5py; f = h5py.File('" + v2 +
                            "', 'r+'); d = f['frontend/n_new'][:]; del f['frontend/n_new']; "
                            "f['frontend/n_new'] = d[:-1]; f.close()\"");
  ASSERT_EQ(cut.exit_code, 0) << cut.output;
  const auto bad = runShell(python_ + " '" + scripts + "/check_results.py' '" + v2 + "'");
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("/frontend columns differ in shape"), std::string::npos) << bad.output;
}

TEST_F(AnalysisTest, NotebooksExecuteOnTheSweep) {
  if (pythonWith("nbformat, nbclient, nbconvert, ipykernel, matplotlib").empty()) {
    GTEST_SKIP() << "Jupyter missing: install the Debian packages jupyter-nbconvert "
                    "python3-ipykernel python3-matplotlib";
  }
  const fs::path out = dir_ / "out";
  const auto result = runCli("notebooks '" + sweep_ + "' --out '" + out.string() + "' --jobs 2");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  for (const std::string name :
       {"sweep", "precision", "runs/vo__kitti-10__ns-qr-sqrt-f32__s1",
        "runs/vo__kitti-10__ns-qr-sqrt-f64__s1", "runs/vio__euroc-MH_01_easy__sc-sc-sq-f32__s1",
        "runs/vio__euroc-MH_01_easy__sc-sc-sq-f64__s1"}) {
    SCOPED_TRACE(name);
    ASSERT_TRUE(fs::is_regular_file(out / (name + ".html")));
    ASSERT_TRUE(fs::is_regular_file(out / (name + ".ipynb")));
    const std::string html = readFile(out / (name + ".html"));
    EXPECT_EQ(html.find("Traceback"), std::string::npos);
    EXPECT_NE(html.find("data:image/png;base64"), std::string::npos) << "no figure";
    EXPECT_EQ(html.find("https://cdn"), std::string::npos) << "loads from the network";
  }
  // The sweep notebook shows the failure matrix with VIO-32's failure frame.
  EXPECT_NE(readFile(out / "sweep.html").find("failed @"), std::string::npos);
  EXPECT_TRUE(fs::is_regular_file(out / "notebooks.json"));
  // The committed notebooks carry no outputs (only the executed copies do).
  const auto clean = runShell(
      python_ + " -c \"import json, glob, sys; cells = [c for p in glob.glob('" + sourceDir() +
      "/notebooks/*.ipynb') for c in json.load(open(p))['cells'] if c['cell_type'] == 'code']; "
      "sys.exit(any(c['outputs'] or c['execution_count'] for c in cells) or not cells)\"");
  EXPECT_EQ(clean.exit_code, 0) << "notebooks/*.ipynb committed with outputs\n" << clean.output;
}

// Starts `marglab ARGS` with SIGINT and SIGTERM at their defaults (a shell without job control
// starts background commands with SIGINT ignored), output to `log`; returns its pid once `log`
// holds `line` (or -1 when it ended before).
pid_t startCliAndWaitFor(const std::vector<std::string>& args, const fs::path& log,
                         const std::string& line) {
  const pid_t pid = fork();
  if (pid == 0) {
    signal(SIGINT, SIG_DFL);
    signal(SIGTERM, SIG_DFL);
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 1);
    dup2(fd, 2);
    std::vector<std::string> all = {test::cliPath()};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  // A wait for an event, bounded so that a broken build fails instead of hanging.
  for (int i = 0; i < 3000; ++i) {
    if (readFile(log).find(line) != std::string::npos) return pid;
    if (waitpid(pid, nullptr, WNOHANG) == pid) return -1;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
  return -1;
}

// Issue 38 item 7: a Ctrl-C while the notebooks ran went on for 16 s, wrote more notebooks, kept
// one with a KeyboardInterrupt traceback and printed Python's traceback; SIGTERM stopped at once.
TEST_F(AnalysisTest, NotebooksStopOnSigintAsOnSigterm) {
  if (pythonWith("nbformat, nbclient, nbconvert, ipykernel, matplotlib").empty()) {
    GTEST_SKIP() << "Jupyter missing";
  }
  const fs::path out = dir_ / "out", log = dir_ / "notebooks.log";
  const pid_t pid = startCliAndWaitFor({"notebooks", sweep_, "--out", out.string(), "--jobs", "2"},
                                       log, "notebooks: executing");
  ASSERT_GT(pid, 0) << readFile(log);
  ASSERT_EQ(kill(pid, SIGINT), 0);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  const std::string output = readFile(log);
  EXPECT_EQ(output.find("Traceback"), std::string::npos) << output;
  EXPECT_NE(output.find("interrupted by SIGINT"), std::string::npos) << output;
  if (fs::is_directory(out)) {
    for (const auto& entry : fs::recursive_directory_iterator(out)) {
      EXPECT_EQ(entry.path().string().find(".tmp-"), std::string::npos) << entry.path();
      EXPECT_EQ(readFile(entry.path()).find("KeyboardInterrupt"), std::string::npos)
          << entry.path();
    }
  }
}

// Issue 38 item 7: SIGTERM during `reproduce`'s sweep stopped the sweep (exit 143), and reproduce
// went on to the tables, the figures and the notebooks of the part that had run (it stopped only
// on the sweep's 130, SIGINT's code). Both signals stop it there, with the sweep's exit code.
TEST_F(AnalysisTest, ReproduceStopsAfterAnInterruptedSweep) {
  for (const int sig : {SIGTERM, SIGINT}) {
    SCOPED_TRACE(sig);
    const std::string name = "reproduce" + std::to_string(sig);
    const fs::path results = dir_ / name, figures = dir_ / (name + "_figures"),
                   log = dir_ / (name + ".log");
    fs::remove_all(results);
    fs::remove_all(figures);
    const pid_t pid = startCliAndWaitFor({"reproduce", "--quick", "--jobs", "1", "--results",
                                          results.string(), "--figures", figures.string()},
                                         log, "sweep quick: 18 runs");
    ASSERT_GT(pid, 0) << readFile(log);
    ASSERT_EQ(kill(pid, sig), 0);
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status)) << readFile(log);
    EXPECT_EQ(WEXITSTATUS(status), 128 + sig) << readFile(log);
    EXPECT_FALSE(fs::exists(results / "quick" / "tables")) << readFile(log);
    EXPECT_FALSE(fs::exists(figures)) << readFile(log);
    EXPECT_EQ(readFile(log).find("notebooks: executing"), std::string::npos) << readFile(log);
  }
}

// Issue 38 item 8: `notebooks --out <unwritable>` ran 21 s and died with a Python traceback.
TEST_F(AnalysisTest, UnwritableOutputsFailBeforeAnyWork) {
  const fs::path file = dir_ / "a_file";
  std::ofstream(file) << "x";
  const std::string under = (file / "out").string();
  for (const std::string verb : {"notebooks", "plot", "report"}) {
    const auto result = runCli(verb + " '" + sweep_ + "' " + (verb == "plot" ? "-o" : "--out") +
                               " '" + under + "'");
    EXPECT_EQ(result.exit_code, 1) << verb << "\n" << result.output;
    EXPECT_NE(result.output.find("marglab: error: " + under + ": cannot create the folder"),
              std::string::npos)
        << result.output;
    EXPECT_EQ(result.output.find("Traceback"), std::string::npos) << result.output;
    EXPECT_EQ(result.output.find("executing"), std::string::npos) << result.output;
  }
}

TEST_F(AnalysisTest, ReportOpensInHeadlessChromium) {
  if (pythonWith("matplotlib, websocket").empty() || !haveChromium()) {
    GTEST_SKIP() << "headless browser check skipped: install the Debian packages chromium "
                    "python3-websocket python3-matplotlib";
  }
  const fs::path out = dir_ / "out";
  const auto result = runCli("report '" + sweep_ + "' --out '" + out.string() + "' --check");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const std::string html = readFile(out / "report.html");
  for (const char* part : {"id=\"failure-matrix\"", "Table 1", "Table 2", "data:image/png;base64",
                           "fig1_euroc-MH_01_easy", "fig7_trajectory_kitti-10", "failed @ 9"}) {
    EXPECT_NE(html.find(part), std::string::npos) << part;
  }
  const std::string png = readFile(out / "report.png");
  ASSERT_GT(png.size(), 10000u);
  EXPECT_EQ(png.substr(1, 3), "PNG");

  // The check fails on a broken page: a console error and an image that does not load.
  std::string broken = html;
  broken.insert(broken.find("</main>"),
                "<img alt=\"gone\" src=\"gone.png\"><script>console.error('broken')</script>");
  std::ofstream(out / "broken.html") << broken;
  const auto check =
      runShell(std::string(pythonWith("websocket")) + " '" + sourceDir() +
               "/tools/scripts/check_report.py' '" + (out / "broken.html").string() + "' --report");
  EXPECT_EQ(check.exit_code, 1) << check.output;
  EXPECT_NE(check.output.find("console.error: broken"), std::string::npos) << check.output;
  EXPECT_NE(check.output.find("gone"), std::string::npos) << check.output;
}

// Issue #19 section 3 (tools/scripts/nfr_length_table.py): a run is causal, so the first N frames
// of a longer nfr run are the N-frame run bit for bit, and the table's prefix ATE reproduces the C++
// ATE of both; a short run of another seed is told apart.
TEST(AnalysisCli, NfrLengthTablePrefixIsTheShortRun) {
  const std::string python = pythonWith("h5py, numpy, pandas");
  if (python.empty()) GTEST_SKIP() << "no python3 with h5py, numpy and pandas";
  const fs::path dir = fs::path(test::binaryDir()) / "test_analysis" / "nfr_length";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "nfr.toml") << "[marginalization]\nstrategy = \"nfr\"\n";
  const auto run = [&](int frames, int seed) {
    const std::string out =
        (dir / ("f" + std::to_string(frames) + "_s" + std::to_string(seed) + ".h5")).string();
    const auto r =
        runCli("run --dataset euroc/MH_03_medium --variant ns-qr-sqrt-f64 --seed " +
               std::to_string(seed) + " --frames " + std::to_string(frames) +
               " --no-diagnostics --config '" + (dir / "nfr.toml").string() + "' -o '" + out + "'");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return out;
  };
  const std::string long_run = run(80, 2);
  const std::string script = std::string(sourceDir()) + "/test/cli/nfr_length_agrees.py";
  const auto agree = runShell(python + " '" + script + "' '" + long_run + "' '" + run(50, 2) + "'");
  EXPECT_EQ(agree.exit_code, 0) << agree.output;
  EXPECT_NE(agree.output.find("AGREE 50 of 80 frames, 1 sparsify events"), std::string::npos)
      << agree.output;
  const auto other = runShell(python + " '" + script + "' '" + long_run + "' '" + run(50, 3) + "'");
  EXPECT_EQ(other.exit_code, 1) << other.output;
  EXPECT_NE(other.output.find("p_est of SHORT differs"), std::string::npos) << other.output;
}

// Issue #40 §3: Fig. 4's yaw measure (plot_paper.py fig4_yaw) on series with known onsets.
TEST(AnalysisCli, Fig4YawOnsetOnConstructedSeries) {
  const std::string python = pythonWith("matplotlib, h5py, numpy");
  if (python.empty()) GTEST_SKIP() << "no python3 with matplotlib, h5py and numpy";
  const auto agree = runShell(python + " '" + sourceDir() + "/test/cli/fig4_yaw_agrees.py'");
  EXPECT_EQ(agree.exit_code, 0) << agree.output;
  EXPECT_NE(agree.output.find("AGREE onset at frame 1202 of 3000"), std::string::npos)
      << agree.output;
}

// Issue #30: the table scripts publish "mean ± std" with the sample std of `marglab tables`,
// align with the project's ATE (not the independent checker's) and write their files atomically.
TEST(AnalysisCli, TableScriptsShareTheSeedStatisticsAndAlignment) {
  const std::string python = pythonWith("h5py, numpy, pandas, scipy");
  if (python.empty()) GTEST_SKIP() << "no python3 with h5py, numpy, pandas and scipy";
  const fs::path dir = fs::path(test::binaryDir()) / "test_analysis" / "table_scripts";
  fs::remove_all(dir);
  const auto agree = runShell(python + " '" + sourceDir() + "/test/cli/table_scripts_agree.py' '" +
                              dir.string() + "'");
  EXPECT_EQ(agree.exit_code, 0) << agree.output;
  EXPECT_NE(agree.output.find("AGREE"), std::string::npos) << agree.output;
}

TEST(AnalysisCli, BadInputNamesTheFile) {
  const fs::path dir = fs::path(test::binaryDir()) / "test_analysis" / "not_a_sweep";
  fs::create_directories(dir);
  for (const std::string verb : {"notebooks", "report"}) {
    const auto result = runCli(verb + " '" + dir.string() + "'");
    EXPECT_EQ(result.exit_code, 1) << result.output;
    EXPECT_NE(result.output.find((dir / "index.csv").string()), std::string::npos) << result.output;
  }
}

}  // namespace
}  // namespace marglab
