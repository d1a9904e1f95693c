// `marglab sweep --backend slurm` on a real one-node Slurm cluster (scripts/slurm_local.sh start;
// .ci/run starts and stops it): the index and the HDF5 estimates equal the local backend's; a
// cancelled task and one over its time limit get the right failure_kind and --resume submits
// exactly those; a submission Slurm rejects leaves the folder resumable. Without a cluster these
// tests skip (the outcome mapping is still checked, without Slurm).

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include "common/cli_runner.h"
#include "core/common/source_dir.h"
#include "core/data/sequence.h"
#include "core/experiment/slurm_backend.h"
#include "core/experiment/slurm_client.h"
#include "core/experiment/sweep_common.h"
#include "core/experiment/sweep_index.h"
#include "core/io/hdf5.h"
#include "core/io/results_file.h"
#include "test_paths.h"

namespace marglab::experiment {
namespace {

namespace fs = std::filesystem;
using test::quote;
using test::readText;
using test::runCli;
using test::runShell;
using test::startCli;

#define REQUIRE_SLURM()                                                                  \
  do {                                                                                   \
    std::string why;                                                                     \
    if (!SlurmClient::available(&why)) {                                                 \
      GTEST_SKIP() << "no Slurm cluster answers (" << why                                \
                   << "); start the one-node cluster with `bash scripts/slurm_local.sh " \
                      "start` (root, Debian slurm-wlm + munge)";                         \
    }                                                                                    \
  } while (0)

const IndexRow* findRow(const std::vector<IndexRow>& rows, const std::string& id) {
  for (const IndexRow& row : rows) {
    if (row.get("id") == id) return &row;
  }
  return nullptr;
}

fs::path freshDir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("marglab_slurm_" + name + "_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// DIR/NAME.toml: a sweep of one VO group, "vo", of the variants (a TOML list's items) on one
// sequence over the first frames.
fs::path writeVoSweep(const fs::path& dir, const std::string& name, const std::string& dataset,
                      const std::string& variants, int frames) {
  const fs::path file = dir / (name + ".toml");
  std::ofstream(file) << "name = \"" << name << "\"\n[[group]]\nname = \"vo\"\ndatasets = [\""
                      << dataset << "\"]\nvariants = [" << variants << "]\nframes = " << frames
                      << "\n";
  return file;
}

std::vector<double> readDoubles(const fs::path& file, const std::string& dataset) {
  const ResultsReader reader(file.string());
  return reader.file().readVector<double>(dataset);
}

// The ids of the tasks of a written sbatch script ("  N) ID=...; set -- ...").
std::set<std::string> scriptIds(const fs::path& script) {
  std::set<std::string> ids;
  const std::regex task(R"(^  [0-9]+\) ID='?([^;']+)'?;)");
  std::istringstream in(readText(script));
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (std::regex_search(line, m, task)) ids.insert(m[1]);
  }
  return ids;
}

TEST(SlurmOutcome, SlurmStatesMapToFailureKinds) {
  const fs::path dir = freshDir("outcome");
  fs::create_directories(dir / "runs");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"TIMEOUT", "timeout"},       {"DEADLINE", "timeout"},
      {"CANCELLED", "interrupted"}, {"OUT_OF_MEMORY", "oom"},
      {"NODE_FAIL", "node"},        {"PREEMPTED", "interrupted"},
      {"FAILED", "exit"},           {"", "exit"}};
  for (const auto& [state, kind] : cases) {
    SCOPED_TRACE(state);
    IndexRow row;
    row.set("id", "x");
    row.set("results", "runs/x.h5");
    row.set("log", "logs/x.log");
    row.set("slurm_job", "7_3");
    row.set("status", "running");
    EXPECT_TRUE(applyTaskOutcome(dir.string(), state, TaskExit{}, "rev", &row));
    EXPECT_EQ(row.get("status"), "failed");
    EXPECT_EQ(row.get("failure_kind"), kind);
    EXPECT_NE(row.get("reason").find("7_3"), std::string::npos) << row.get("reason");
  }
  // Still queued or running: not an outcome yet.
  for (const std::string state : {"PENDING", "RUNNING", "COMPLETING"}) {
    IndexRow row;
    row.set("slurm_job", "7_3");
    EXPECT_FALSE(applyTaskOutcome(dir.string(), state, TaskExit{}, "rev", &row)) << state;
    EXPECT_EQ(row.get("status"), state == "PENDING" ? "pending" : "running");
  }
  // A task killed by SIGTERM that Slurm has forgotten: its exit file says so.
  TaskExit exit;
  exit.present = true;
  exit.signal = "TERM";
  exit.start = 100;
  exit.end = 160.5;
  IndexRow row;
  row.set("results", "runs/x.h5");
  row.set("slurm_job", "7_3");
  ASSERT_TRUE(applyTaskOutcome(dir.string(), "", exit, "rev", &row));
  EXPECT_EQ(row.get("failure_kind"), "signal");
  EXPECT_EQ(row.number("wall_s"), 60.5);
  fs::remove_all(dir);
}

// The same short sweep through both backends: same index values, bit-identical estimates.
TEST(SlurmSweep, IndexAndEstimatesEqualTheLocalBackend) {
  REQUIRE_SLURM();
  const fs::path dir = freshDir("equal");
  std::ofstream(dir / "eq.toml") << R"(name = "eq"
[[group]]
name = "vo"
datasets = ["kitti/10"]
variants = ["headline"]
frames = 40
[[group]]
name = "nan"
datasets = ["kitti/04"]
variants = ["ns-qr-sqrt-f32"]
frames = 30
args = ["--inject-nan-frame", "12"]
)";
  const auto local =
      runCli("sweep " + quote(dir / "eq.toml") + " --jobs 2 --out " + quote(dir / "local"));
  ASSERT_EQ(local.exit_code, 0) << local.output;
  const auto slurm = runCli("sweep " + quote(dir / "eq.toml") +
                            " --backend slurm --wait --jobs 2 --out " + quote(dir / "slurm"));
  ASSERT_EQ(slurm.exit_code, 0) << slurm.output;
  EXPECT_NE(slurm.output.find("4 ok, 1 failed numerically, 0 crashed"), std::string::npos)
      << slurm.output;
  const auto a = readIndex((dir / "local" / "index.csv").string());
  const auto b = readIndex((dir / "slurm" / "index.csv").string());
  ASSERT_EQ(a.size(), b.size());
  for (const IndexRow& row : a) {
    SCOPED_TRACE(row.get("id"));
    const IndexRow* other = findRow(b, row.get("id"));
    ASSERT_NE(other, nullptr);
    for (const char* column : {"status", "failure_kind", "failure_frame", "reason", "ate_rmse",
                               "n_frames", "command", "exit_code"}) {
      EXPECT_EQ(row.get(column), other->get(column)) << column;
    }
    EXPECT_NE(other->get("slurm_job"), "");
    for (const char* dataset : {"/frames/p_est", "/frames/q_est"}) {
      const auto x = readDoubles(dir / "local" / row.get("results"), dataset);
      const auto y = readDoubles(dir / "slurm" / other->get("results"), dataset);
      ASSERT_EQ(x.size(), y.size()) << dataset;
      EXPECT_EQ(std::memcmp(x.data(), y.data(), x.size() * sizeof(double)), 0) << dataset;
    }
  }
  // The exact script is kept, with the throttle from --jobs; tables read the folder unchanged.
  const std::string script = readText(dir / "slurm" / "slurm" / "array-1.sbatch");
  EXPECT_NE(script.find("#SBATCH --array=0-4%2"), std::string::npos) << script;
  const auto tables = runCli("tables " + quote(dir / "slurm") + " --format csv");
  EXPECT_EQ(tables.exit_code, 0) << tables.output;
  fs::remove_all(dir);
}

// Issue #29: a `frontend = "images"` sweep tracks each dataset once, as the local backend does —
// here in a tracking job the run arrays depend on (before, the runs found no track file).
// A sweep of `marglab ba` runs (group kind "ba") on Slurm: each task runs `marglab ba --spec`, and
// the index (status, final cost) and the cost series equal the local backend's (ns-f64 and
// ceres-sparse on one thread are deterministic).
TEST(SlurmSweep, BaRunsEqualTheLocalBackend) {
  REQUIRE_SLURM();
  const fs::path dir = freshDir("ba");
  std::ofstream(dir / "ba.toml") << "name = \"ba\"\n[[group]]\nname = \"g\"\nkind = \"ba\"\n"
                                 << "problems = [\""
                                 << std::string(sourceDir()) + "/datasets/bal/dubrovnik-3-7-pre.txt"
                                 << "\"]\nsolvers = [\"ns-f64\", \"ceres-sparse\"]\n"
                                 << "seeds = [1, 2]\niterations = 5\nperturb_sigma = 0.01\n";
  const auto local =
      runCli("sweep " + quote(dir / "ba.toml") + " --jobs 2 --out " + quote(dir / "local"));
  ASSERT_EQ(local.exit_code, 0) << local.output;
  const auto slurm = runCli("sweep " + quote(dir / "ba.toml") +
                            " --backend slurm --wait --jobs 2 --out " + quote(dir / "slurm"));
  ASSERT_EQ(slurm.exit_code, 0) << slurm.output;
  EXPECT_NE(slurm.output.find("4 ok"), std::string::npos) << slurm.output;
  const auto a = readIndex((dir / "local" / "index.csv").string());
  const auto b = readIndex((dir / "slurm" / "index.csv").string());
  ASSERT_EQ(a.size(), b.size());
  for (const IndexRow& row : a) {
    SCOPED_TRACE(row.get("id"));
    const IndexRow* other = findRow(b, row.get("id"));
    ASSERT_NE(other, nullptr);
    for (const char* column :
         {"status", "kind", "ba_status", "final_cost", "initial_cost", "command", "exit_code"}) {
      EXPECT_EQ(row.get(column), other->get(column)) << column;
    }
    EXPECT_NE(other->get("slurm_job"), "");
    EXPECT_NE(readText(dir / "slurm" / "slurm" / "array-1.sbatch").find("ba --spec runs/"),
              std::string::npos);
    const auto x = h5::File::openReadOnly((dir / "local" / row.get("results")).string())
                       .readVector<double>("iterations/cost");
    const auto y = h5::File::openReadOnly((dir / "slurm" / other->get("results")).string())
                       .readVector<double>("iterations/cost");
    EXPECT_EQ(x, y);
  }
  fs::remove_all(dir);
}

TEST(SlurmSweep, ImagesAreTrackedOncePerDatasetInAJobTheRunsDependOn) {
  REQUIRE_SLURM();
  const fs::path dir = freshDir("images");
  std::ofstream(dir / "img.toml") << R"(name = "img"
[[group]]
name = "images"
datasets = ["euroc/V1_01_easy_images"]
variants = ["ns-qr-sqrt-f64", "sc-sc-sq-f64"]
frontend = "images"
frames = 5
)";
  const auto local =
      runCli("sweep " + quote(dir / "img.toml") + " --jobs 2 --out " + quote(dir / "local"));
  ASSERT_EQ(local.exit_code, 0) << local.output;
  const fs::path out = dir / "slurm";
  const auto slurm = runCli("sweep " + quote(dir / "img.toml") +
                            " --backend slurm --wait --jobs 2 --out " + quote(out));
  ASSERT_EQ(slurm.exit_code, 0) << slurm.output;
  EXPECT_NE(slurm.output.find("2 ok, 0 failed numerically, 0 crashed"), std::string::npos)
      << slurm.output;
  const std::string track_id = "tracks_euroc-V1_01_easy_images";
  EXPECT_EQ(scriptIds(out / "slurm" / "array-1.sbatch"), std::set<std::string>{track_id});
  EXPECT_NE(readText(out / "slurm" / "array-1.sbatch").find("datasets track"), std::string::npos);
  const std::regex tracking_job(R"(submitted tracking job ([0-9]+) )");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(slurm.output, m, tracking_job)) << slurm.output;
  EXPECT_NE(readText(out / "slurm" / "array-2.sbatch")
                .find("#SBATCH --dependency=afterok:" + m[1].str() + "\n"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(out / "slurm" / "array-3.sbatch"));  // tracked once
  EXPECT_TRUE(fs::is_regular_file(out / "tracks/euroc-V1_01_easy_images.h5"));
  EXPECT_NE(readText(out / "logs" / (track_id + ".log")).find("wrote"), std::string::npos);
  const auto a = readIndex((dir / "local" / "index.csv").string());
  const auto b = readIndex((out / "index.csv").string());
  ASSERT_EQ(a.size(), b.size());
  for (const IndexRow& row : a) {
    SCOPED_TRACE(row.get("id"));
    const IndexRow* other = findRow(b, row.get("id"));
    ASSERT_NE(other, nullptr);
    EXPECT_EQ(other->get("status"), "ok");
    EXPECT_EQ(row.get("ate_rmse"), other->get("ate_rmse"));
  }
  fs::remove_all(dir);
}

// A dataset whose tracking job fails: Slurm cancels the runs that depend on it, and the index says
// why (the tracking failed, its log) instead of "cancelled in Slurm".
TEST(SlurmSweep, FailedTrackingJobFailsItsRunsSayingWhy) {
  REQUIRE_SLURM();
  const fs::path dir = freshDir("badtracks");
  // A user's ASL folder of 3 frames whose second left image is cut short.
  const fs::path shipped = fs::path(datasetsRoot()) / "euroc/V1_01_easy_images/mav0";
  const fs::path mav = dir / "clip/mav0";
  for (const char* cam : {"cam0", "cam1"}) {
    fs::create_directories(mav / cam / "data");
    fs::copy_file(shipped / cam / "sensor.yaml", mav / cam / "sensor.yaml");
    std::istringstream in(readText(shipped / cam / "data.csv"));
    std::ofstream csv(mav / cam / "data.csv");
    std::string line;
    for (int i = 0; i < 4 && std::getline(in, line); ++i) {
      csv << line << "\n";
      if (i > 0) {
        const std::string file = line.substr(line.find(',') + 1);
        fs::copy_file(shipped / cam / "data" / file, mav / cam / "data" / file);
        if (i == 2 && std::string(cam) == "cam0") fs::resize_file(mav / cam / "data" / file, 100);
      }
    }
  }
  std::ofstream(dir / "bad.toml")
      << "name = \"bad\"\n[[group]]\nname = \"images\"\ndatasets = [\"" << (dir / "clip").string()
      << "\"]\nvariants = [\"ns-qr-sqrt-f64\"]\nfrontend = \"images\"\n";
  const fs::path out = dir / "out";
  const auto sweep =
      runCli("sweep " + quote(dir / "bad.toml") + " --backend slurm --wait --out " + quote(out));
  EXPECT_EQ(sweep.exit_code, 1) << sweep.output;
  const auto rows = readIndex((out / "index.csv").string());
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].get("failure_kind"), "error") << rows[0].get("reason");
  EXPECT_NE(rows[0].get("reason").find("tracking the images of " + (dir / "clip").string() +
                                       " failed (exit 1)"),
            std::string::npos)
      << rows[0].get("reason");
  EXPECT_NE(rows[0].get("reason").find("the file ends early"), std::string::npos)
      << rows[0].get("reason");
  fs::remove_all(dir);
}

// The state of one task as squeue shows it ("" when unknown).
std::string taskState(const std::string& task) {
  const auto r = runShell("squeue -h -t all -j " + task + " -o %T");
  return r.exit_code == 0 ? r.output.substr(0, r.output.find('\n')) : "";
}

TEST(SlurmSweep, CancelledAndTimedOutTasksAreRecordedAndResumeSubmitsExactlyThem) {
  REQUIRE_SLURM();
  const fs::path dir = freshDir("cancel");
  // Two runs of several minutes: one over a 1-minute limit (timeout_s 1 → --time=1, Slurm's
  // smallest), one cancelled; a short one that succeeds. The limited run takes many minutes on any
  // machine (a 40-keyframe window; magistrale1 alone takes under a minute on an idle machine), and
  // its position bound is lifted so that it cannot end as a numerical failure first.
  std::ofstream(dir / "c.toml") << R"(name = "c"
[[group]]
name = "limit"
datasets = ["tumvi/magistrale1"]
variants = ["ns-qr-sqrt-f64"]
timeout_s = 1
config = { window = { max_kfs = 40 }, failure = { max_position_error_m = 1000.0 } }
[[group]]
name = "cancel"
datasets = ["tumvi/magistrale1"]
variants = ["ns-qr-sqrt-f32"]
[[group]]
name = "short"
datasets = ["kitti/04"]
variants = ["ns-qr-sqrt-f64"]
frames = 20
)";
  const fs::path out = dir / "out";
  const auto submit =
      runCli("sweep " + quote(dir / "c.toml") + " --backend slurm --out " + quote(out));
  ASSERT_EQ(submit.exit_code, 0) << submit.output;
  auto rows = readIndex((out / "index.csv").string());
  const std::string limit_id = "limit__tumvi-magistrale1__ns-qr-sqrt-f64__s1";
  const std::string cancel_id = "cancel__tumvi-magistrale1__ns-qr-sqrt-f32__s1";
  const std::string short_id = "short__kitti-04__ns-qr-sqrt-f64__s1";
  const std::string cancel_task = findRow(rows, cancel_id)->get("slurm_job");
  ASSERT_FALSE(cancel_task.empty());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (taskState(cancel_task) != "RUNNING" && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  ASSERT_EQ(taskState(cancel_task), "RUNNING");
  ASSERT_EQ(runShell("scancel " + cancel_task).exit_code, 0);

  const auto status = runCli("sweep --status " + quote(out) + " --wait");
  EXPECT_EQ(status.exit_code, 1) << status.output;  // killed runs make the sweep fail
  rows = readIndex((out / "index.csv").string());
  EXPECT_EQ(findRow(rows, limit_id)->get("failure_kind"), "timeout") << status.output;
  EXPECT_EQ(findRow(rows, cancel_id)->get("failure_kind"), "interrupted") << status.output;
  EXPECT_EQ(findRow(rows, short_id)->get("status"), "ok") << status.output;
  for (const auto& entry : fs::directory_iterator(out / "runs")) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos) << entry.path();
  }

  // --resume submits the two failed runs and nothing else (then they are cancelled again).
  const auto resume =
      runCli("sweep " + quote(dir / "c.toml") + " --backend slurm --resume --out " + quote(out));
  ASSERT_EQ(resume.exit_code, 0) << resume.output;
  EXPECT_NE(resume.output.find("(Slurm; 2 to submit)"), std::string::npos) << resume.output;
  std::set<std::string> resubmitted;
  for (const char* script : {"array-3.sbatch", "array-4.sbatch"}) {
    for (const std::string& id : scriptIds(out / "slurm" / script)) resubmitted.insert(id);
  }
  EXPECT_EQ(resubmitted, (std::set<std::string>{limit_id, cancel_id}));
  EXPECT_FALSE(fs::exists(out / "slurm" / "array-5.sbatch"));
  rows = readIndex((out / "index.csv").string());
  EXPECT_EQ(findRow(rows, short_id)->get("reused"), "1");
  std::set<std::string> jobs;
  for (const std::string& id : {limit_id, cancel_id}) {
    const std::string task = findRow(rows, id)->get("slurm_job");
    jobs.insert(task.substr(0, task.find('_')));
  }
  for (const std::string& job : jobs) runShell("scancel " + job);
  const auto after = runCli("sweep --status " + quote(out) + " --wait");
  rows = readIndex((out / "index.csv").string());
  EXPECT_EQ(findRow(rows, cancel_id)->get("failure_kind"), "interrupted") << after.output;
  fs::remove_all(dir);
}

TEST(SlurmSweep, RejectedSubmissionFailsWithSlurmsMessageAndStaysResumable) {
  REQUIRE_SLURM();
  const fs::path dir = freshDir("reject");
  const fs::path toml =
      writeVoSweep(dir, "r", "kitti/04", "\"ns-qr-sqrt-f64\", \"sc-sc-sq-f64\"", 20);
  const fs::path out = dir / "out";
  const auto rejected =
      runCli("sweep " + quote(toml) +
             " --backend slurm --slurm-arg=--partition=no_such_partition --out " + quote(out));
  EXPECT_EQ(rejected.exit_code, 1) << rejected.output;
  EXPECT_NE(rejected.output.find("Invalid partition name specified"), std::string::npos)
      << rejected.output;
  auto rows = readIndex((out / "index.csv").string());
  ASSERT_EQ(rows.size(), 2u);
  for (const IndexRow& row : rows) {
    EXPECT_EQ(row.get("status"), "pending");
    EXPECT_EQ(row.get("slurm_job"), "");
  }
  const auto resume =
      runCli("sweep " + quote(toml) + " --backend slurm --resume --wait " + "--out " + quote(out));
  ASSERT_EQ(resume.exit_code, 0) << resume.output;
  rows = readIndex((out / "index.csv").string());
  for (const IndexRow& row : rows) EXPECT_EQ(row.get("status"), "ok") << row.get("id");
  fs::remove_all(dir);
}

// The Slurm backend takes the sweep folder's lock too (sweep_common.h): a folder held by another
// sweep (here this test process) is refused before anything is submitted or written.
TEST(SlurmSweep, LockedFolderIsRefusedNamingTheOwner) {
  REQUIRE_SLURM();
  const fs::path dir = freshDir("lock");
  const fs::path toml = writeVoSweep(dir, "l", "kitti/04", "\"ns-qr-sqrt-f64\"", 20);
  const fs::path out = dir / "out";
  const detail::SweepLock lock(out);
  const auto refused = runCli("sweep " + quote(toml) + " --backend slurm --out " + quote(out));
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_NE(refused.output.find("in use by another marglab sweep (pid " + std::to_string(getpid())),
            std::string::npos)
      << refused.output;
  EXPECT_FALSE(fs::exists(out / "index.csv"));
  fs::remove_all(dir);
}

// A sweep that submitted and returned leaves its tasks queued and no lock: a --force sweep into
// that folder must not delete what those tasks will write. It is refused, naming the jobs to
// cancel, and the folder is left as it was.
TEST(SlurmSweep, ForceIsRefusedWhileTheFoldersTasksAreStillQueued) {
  REQUIRE_SLURM();
  const fs::path dir = freshDir("queued");
  const fs::path toml = writeVoSweep(dir, "q", "kitti/10", "\"headline\"", 600);
  const fs::path out = dir / "out";
  const std::string sweep = "sweep " + quote(toml) + " --backend slurm --jobs 1 ";
  const auto submit = runCli(sweep + "--out " + quote(out));
  ASSERT_EQ(submit.exit_code, 0) << submit.output;
  // Each row's task: the refused sweep may bring the states up to date, not the tasks.
  const auto tasks = [&out] {
    std::vector<std::string> ids_and_tasks;
    for (const IndexRow& row : readIndex((out / "index.csv").string())) {
      ids_and_tasks.push_back(row.get("id") + " " + row.get("slurm_job"));
    }
    return ids_and_tasks;
  };
  const std::vector<std::string> tasks_before = tasks();
  const std::string job = readIndex((out / "index.csv").string()).front().get("slurm_job");
  const std::string array = job.substr(0, job.find('_'));
  ASSERT_FALSE(array.empty()) << submit.output;

  const auto force = runCli(sweep + "--force --out " + quote(out));
  EXPECT_EQ(force.exit_code, 2) << force.output;
  EXPECT_NE(force.output.find("still queued in Slurm (jobs " + array + ")"), std::string::npos)
      << force.output;
  EXPECT_NE(force.output.find("cancel them first (scancel " + array + ")"), std::string::npos)
      << force.output;
  EXPECT_EQ(tasks(), tasks_before);
  EXPECT_TRUE(fs::exists(out / "slurm" / "array-1.sbatch"));
  EXPECT_TRUE(fs::exists(out / "runs"));

  runShell("scancel " + array);
  runCli("sweep --status " + quote(out) + " --wait");
  fs::remove_all(dir);
}

TEST(SlurmSweep, CtrlCWhileFollowingCancelsTheArrayAndForceWaitsForIt) {
  REQUIRE_SLURM();
  const fs::path dir = freshDir("sigint");
  const fs::path toml = writeVoSweep(dir, "i", "kitti/10", "\"headline\"", 600);
  const fs::path out = dir / "out";
  const pid_t sweep = startCli({"sweep", toml.string(), "--backend", "slurm", "--wait", "--jobs",
                                "1", "--out", out.string()},
                               (dir / "sweep.log").string());
  ASSERT_GT(sweep, 0);
  std::string first_task;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    try {
      first_task = readIndex((out / "index.csv").string()).front().get("slurm_job");
    } catch (const std::exception&) {
      continue;  // not written yet
    }
    if (!first_task.empty() && taskState(first_task) == "RUNNING") break;
  }
  ASSERT_EQ(taskState(first_task), "RUNNING") << readText(dir / "sweep.log");
  // --force must not start a new sweep under tasks still running in the folder: while the sweep
  // follows them it holds the folder's lock, and the second sweep is refused naming it.
  const auto force =
      runCli("sweep " + quote(toml) + " --backend slurm --force --out " + quote(out));
  EXPECT_EQ(force.exit_code, 1) << force.output;
  EXPECT_NE(force.output.find("in use by another marglab sweep (pid " + std::to_string(sweep)),
            std::string::npos)
      << force.output;

  ASSERT_EQ(kill(sweep, SIGINT), 0);
  int status = 0;
  ASSERT_EQ(waitpid(sweep, &status, 0), sweep);
  const std::string log = readText(dir / "sweep.log");
  ASSERT_TRUE(WIFEXITED(status)) << log;
  EXPECT_EQ(WEXITSTATUS(status), 130) << log;
  int interrupted = 0;
  for (const IndexRow& row : readIndex((out / "index.csv").string())) {
    SCOPED_TRACE(row.get("id"));
    EXPECT_TRUE(row.get("status") == "ok" || row.get("failure_kind") == "interrupted") << log;
    interrupted += row.get("failure_kind") == "interrupted";
    const std::string state = taskState(row.get("slurm_job"));
    EXPECT_FALSE(isActiveState(state)) << state;
  }
  EXPECT_GE(interrupted, 3) << log;  // one task at a time: at most the first one finished
  fs::remove_all(dir);
}

}  // namespace
}  // namespace marglab::experiment
