#include "core/experiment/slurm_backend.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "core/common/error.h"
#include "core/common/subprocess.h"
#include "core/common/utc_time.h"
#include "core/experiment/slurm_client.h"
#include "core/experiment/slurm_reconcile.h"
#include "core/experiment/slurm_script.h"
#include "core/experiment/sweep_common.h"
#include "marglab/version.h"

namespace marglab::experiment {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// The binary and git revision that planned the folder's Slurm submissions (slurm/binary.txt).
struct Provenance {
  std::string executable;
  std::string revision;
};

Provenance readProvenance(const fs::path& out) {
  std::istringstream in(detail::readTextFile((out / "slurm" / "binary.txt").string()));
  Provenance p;
  std::getline(in, p.executable);
  std::getline(in, p.revision);
  return p;
}

void writeProvenance(const fs::path& out, const Provenance& p) {
  writeFileAtomically((out / "slurm" / "binary.txt").string(),
                      p.executable + "\n" + p.revision + "\n");
}

}  // namespace

namespace {

// A run whose tracking job failed is cancelled by Slurm (--kill-on-invalid-dep), which reads as
// "cancelled in Slurm": say that its images could not be tracked, and where the log is.
void explainTrackingFailure(const fs::path& out, IndexRow* row) {
  if (row->get("status") != "failed" || row->get("failure_kind") != "interrupted") return;
  const std::string& dataset = row->get("dataset");
  if (row->get("command").find("--tracks tracks/" + slug(dataset) + ".h5") == std::string::npos) {
    return;
  }
  const std::string id = "tracks_" + slug(dataset);
  const TaskExit exit = readTaskExit((out / "slurm" / "exit" / id).string());
  if (!exit.present || !exit.signal.empty() || exit.exit_code == 0) return;
  const fs::path log = out / "logs" / (id + ".log");
  row->set("failure_kind", "error");
  row->set("reason",
           fmt::format("tracking the images of {} failed (exit {}): {} (see {})", dataset,
                       exit.exit_code, detail::lastNonEmptyLine(log.string()), log.string()));
}

// Submits queued rows as job arrays, one per distinct time limit, longest runs first.
class Submitter {
 public:
  Submitter(const SweepPlan& plan, const SweepOptions& options, fs::path out, Provenance binary)
      : plan_(plan), options_(options), out_(std::move(out)), binary_(std::move(binary)) {}

  // rows[i] belongs to plan.runs[i]. Throws InputError with sbatch's message; the rows of an
  // array Slurm rejected stay pending without a job (--resume submits them again).
  std::vector<std::string> submit(const std::vector<std::size_t>& queue,
                                  std::vector<IndexRow>* rows) {
    const std::map<std::string, std::string> tracking = submitTracking(queue);
    std::map<std::string, std::vector<std::size_t>> by_time;
    for (std::size_t i : queue) by_time[timeOf(plan_.runs[i])].push_back(i);
    std::vector<std::string> jobs;
    for (const auto& [tracks, job] : tracking) {
      jobs.push_back(job);
      tracking_jobs_.push_back(job);
    }
    for (const auto& [time, indices] : by_time) {
      std::set<std::string> after_ok;
      for (std::size_t i : indices) {
        const auto it = tracking.find(sweepTrackFile(plan_.runs[i]));
        if (plan_.runs[i].frontend == FrontendKind::kImages && it != tracking.end())
          after_ok.insert(it->second);
      }
      jobs.push_back(submitArray(time, indices, {after_ok.begin(), after_ok.end()}, rows));
    }
    return jobs;
  }

  // What was submitted, in order: the tracking jobs, then the run arrays.
  const std::vector<std::string>& describedJobs() const { return described_; }
  const std::vector<std::string>& trackingJobs() const { return tracking_jobs_; }

 private:
  std::string timeOf(const PlannedRun& run) const {
    return options_.slurm.time.empty() ? slurmTimeForTimeout(run.timeout_s) : options_.slurm.time;
  }

  SlurmArraySpec spec(const std::string& time) const {
    SlurmArraySpec s;
    s.sweep_name = plan_.name;
    s.sweep_dir = out_.string();
    s.executable = binary_.executable;
    s.revision = binary_.revision;
    s.time = time;
    s.throttle = options_.jobs;
    s.partition = options_.slurm.partition;
    s.mem = options_.slurm.mem;
    s.cpus = options_.slurm.cpus;
    s.extra = options_.slurm.extra;
    return s;
  }

  std::string nextScriptPath() const {
    for (int n = 1;; ++n) {
      const fs::path p = out_ / "slurm" / fmt::format("array-{}.sbatch", n);
      if (!fs::exists(p)) return p.string();
    }
  }

  // The image front-end once per dataset of the queued `frontend = "images"` runs, on a compute
  // node like the runs (a one-task array each; the run arrays depend on it, slurm_script.h). A
  // track file kept by --resume is reused. Returns track file → job id.
  std::map<std::string, std::string> submitTracking(const std::vector<std::size_t>& queue) {
    std::map<std::string, std::string> jobs;
    for (std::size_t i : queue) {
      const PlannedRun& run = plan_.runs[i];
      const std::string tracks = sweepTrackFile(run);
      if (run.frontend != FrontendKind::kImages || jobs.count(tracks)) continue;
      if (options_.resume && fs::exists(out_ / tracks)) continue;
      fs::create_directories(out_ / "tracks");
      SlurmArraySpec s = spec(timeOf(run));
      s.throttle = 0;
      s.tasks.push_back({"tracks_" + slug(run.dataset),
                         {"datasets", "track", "--dataset", run.dataset, "-o", tracks}});
      jobs[tracks] = submitScript(s, 1);
      described_.push_back(fmt::format("tracking job {} ({})", jobs[tracks], run.dataset));
    }
    return jobs;
  }

  std::string submitArray(const std::string& time, const std::vector<std::size_t>& indices,
                          const std::vector<std::string>& after_ok, std::vector<IndexRow>* rows) {
    SlurmArraySpec s = spec(time);
    s.after_ok = after_ok;
    for (std::size_t i : indices) {
      IndexRow& row = (*rows)[i];
      detail::prepareRunFiles(out_, plan_.name, plan_.runs[i], &row);
      row.set("status", "pending");
      s.tasks.push_back(
          {row.get("id"), childArguments(plan_.runs[i], row.get("results"), row.get("config"))});
    }
    const std::string job = submitScript(s, indices.size());
    for (std::size_t k = 0; k < indices.size(); ++k) {
      (*rows)[indices[k]].set("slurm_job", fmt::format("{}_{}", job, k));
    }
    described_.push_back(fmt::format("job array {} ({})", job, scripts_.back()));
    return job;
  }

  // Writes and submits the script; throws InputError with Slurm's message.
  std::string submitScript(const SlurmArraySpec& s, std::size_t tasks) {
    const std::string script = nextScriptPath();
    writeFileAtomically(script, sbatchScript(s));
    scripts_.push_back(script);
    const std::string job = SlurmClient().submit(script);
    std::ofstream log(out_ / "slurm" / "submissions.log", std::ios::app);
    log << utcNowIso8601() << " job " << job << " " << tasks << " task(s) "
        << fs::path(script).filename().string() << " revision " << binary_.revision << "\n";
    return job;
  }

  const SweepPlan& plan_;
  const SweepOptions& options_;
  fs::path out_;
  Provenance binary_;
  std::vector<std::string> scripts_;
  std::vector<std::string> described_;
  std::vector<std::string> tracking_jobs_;
};

// Follows the queued rows until none is left: a line per finished run, the status line, Ctrl-C
// cancels the arrays.
class Follower {
 public:
  Follower(std::string name, fs::path out, std::string revision, const SweepOptions& options)
      : name_(std::move(name)),
        out_(std::move(out)),
        index_path_((out_ / "index.csv").string()),
        reconciler_(out_, std::move(revision)),
        options_(options) {}

  // Jobs without index rows (the tracking jobs) to cancel with the arrays on Ctrl-C.
  void alsoCancel(std::vector<std::string> jobs) { also_cancel_ = std::move(jobs); }

  // Returns the SIGINT / SIGTERM that interrupted it, 0 when none did.
  int run(std::vector<IndexRow>* rows) {
    total_ = static_cast<int>(std::count_if(rows->begin(), rows->end(), isUnresolvedTask));
    const StopSignals stop;
    const auto start = Clock::now();
    auto stop_time = Clock::time_point::max();
    while (true) {
      if (StopSignals::received() != 0 && stop_time == Clock::time_point::max()) {
        cancelAll(*rows);
        stop_time = Clock::now();
      }
      for (std::size_t i : reconciler_.update(rows)) {
        explainTrackingFailure(out_, &(*rows)[i]);
        announce((*rows)[i]);
      }
      writeIndex(index_path_, *rows);
      if (unresolvedJobs(*rows).empty()) break;
      // Cancelled tasks end within Slurm's KillWait; do not hang on a controller that is gone.
      if (Clock::now() - stop_time > std::chrono::seconds(90)) break;
      statusLine(*rows, start);
      std::this_thread::sleep_for(std::chrono::duration<double>(options_.slurm.poll_s));
    }
    if (options_.status_line) fmt::print(stderr, "\r\033[K");
    return StopSignals::received();
  }

 private:
  void cancelAll(const std::vector<IndexRow>& rows) {
    std::string message;
    // A tracking job that has ended is no longer known to scancel: nothing to report then.
    if (!also_cancel_.empty()) SlurmClient().cancel(also_cancel_, &message);
    const std::set<std::string> jobs = unresolvedJobs(rows);
    if (!SlurmClient().cancel({jobs.begin(), jobs.end()}, &message)) {
      fmt::print(stderr, "\nmarglab sweep: scancel failed: {}\n", message);
    }
  }

  void announce(const IndexRow& row) {
    ++finished_;
    if (options_.status_line) fmt::print(stderr, "\r\033[K");
    // A task cancelled before it started has no wall time.
    const double wall = row.number("wall_s");
    const std::string wall_text = std::isfinite(wall) ? fmt::format("{:.1f}", wall) : "-";
    fmt::print(options_.out, "[{:>{}}/{}] {:<6} {:>7} s  {}  {}\n", finished_,
               std::to_string(total_).size(), total_, row.get("status"), wall_text, row.get("id"),
               detail::outcomeText(row));
    std::fflush(options_.out);
  }

  void statusLine(const std::vector<IndexRow>& rows, Clock::time_point start) const {
    if (!options_.status_line) return;
    int running = 0, pending = 0, failed = 0;
    double done_wall = 0;
    for (const IndexRow& row : rows) {
      if (row.get("slurm_job").empty()) continue;
      running += row.get("status") == "running";
      pending += row.get("status") == "pending";
      failed += row.get("status") == "failed";
      if (!isUnresolvedTask(row) && std::isfinite(row.number("wall_s")))
        done_wall += row.number("wall_s");
    }
    const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
    // ETA: mean wall time of the finished runs × the runs left, spread over those running.
    const double eta = finished_ > 0
                           ? done_wall / finished_ * (running + pending) / std::max(1, running)
                           : std::nan("");
    fmt::print(stderr,
               "\r\033[K  sweep {} (Slurm): {}/{} done, {} running, {} pending, {} failed  {} "
               "elapsed  ETA {}",
               name_, finished_, total_, running, pending, failed, detail::formatDuration(elapsed),
               detail::formatDuration(eta));
    std::fflush(stderr);
  }

  std::string name_;
  fs::path out_;
  std::string index_path_;
  SlurmReconciler reconciler_;
  const SweepOptions& options_;
  std::vector<std::string> also_cancel_;
  int total_ = 0;
  int finished_ = 0;
};

// The closing summary; the exit code of `sweep`.
// stop_signal: the SIGINT / SIGTERM that interrupted the follower, 0 if none. slurm: the folder
// holds Slurm submissions (else it is a local sweep's, whose rows left were never run).
int report(const std::string& name, const std::vector<IndexRow>& rows, const fs::path& out,
           double wall_s, int stop_signal, std::FILE* stream, bool slurm = true) {
  int ok = 0, reused = 0, queued = 0, unsubmitted = 0;
  FailureCounts failed;
  for (const IndexRow& row : rows) {
    const std::string& status = row.get("status");
    reused += !row.get("reused").empty();
    if (status == "ok") {
      ++ok;
    } else if (status == "failed") {
      failed.add(row);
    } else if (isUnresolvedTask(row)) {
      ++queued;
    } else {
      ++unsubmitted;
    }
  }
  fmt::print(
      stream, "sweep {}: {} ok, {}{}{}{} in {:.1f} s\n", name, ok, failed.text(),
      reused ? fmt::format(" ({} kept from an earlier invocation)", reused) : "",
      queued ? fmt::format(", {} still queued in Slurm", queued) : "",
      unsubmitted ? fmt::format(", {} not {}", unsubmitted, slurm ? "submitted" : "run") : "",
      wall_s);
  fmt::print(stream, "  index {}\n", (out / "index.csv").string());
  if (stop_signal != 0) {
    fmt::print(stream, "  interrupted by {}: the arrays were cancelled; continue with --resume\n",
               detail::signalName(stop_signal));
    return exitCodeForSignal(stop_signal);
  }
  if (queued > 0) {
    fmt::print(stream, "  follow: marglab sweep --status {} [--wait]\n", out.string());
  }
  if (!slurm && unsubmitted > 0) {
    fmt::print(stream,
               "  a local sweep that was stopped: continue it with marglab sweep {} "
               "--resume --out {}\n",
               (out / "sweep.toml").string(), out.string());
  }
  return failed.processFailures() > 0 || unsubmitted > 0 ? 1 : 0;
}

}  // namespace

namespace {

// The rows of an earlier submission into this folder whose task may still run (the earlier index
// reconciled with Slurm first).
std::map<std::string, IndexRow> queuedEarlier(const fs::path& out) {
  const fs::path index = out / "index.csv";
  const Provenance earlier = readProvenance(out);
  if (!fs::exists(index) || earlier.revision.empty()) return {};
  std::vector<IndexRow> rows = readIndex(index.string());
  SlurmReconciler(out, earlier.revision).update(&rows);
  writeIndex(index.string(), rows);
  std::map<std::string, IndexRow> queued;
  for (IndexRow& row : rows) {
    if (isUnresolvedTask(row)) queued[row.get("id")] = std::move(row);
  }
  return queued;
}

// Queued tasks stay (and are not submitted twice) only when --resume plans them identically with
// the same revision; --force must not start a new sweep under tasks still writing into the folder.
void checkQueuedMayStay(const fs::path& out, const SweepPlan& plan,
                        const std::map<std::string, IndexRow>& queued, bool force) {
  if (queued.empty()) return;
  std::set<std::string> jobs;
  for (const auto& [id, row] : queued) jobs.insert(jobOf(row.get("slurm_job")));
  const std::string job_list = fmt::format("{}", fmt::join(jobs, " "));
  const std::string revision = readProvenance(out).revision;
  const std::string what = fmt::format(
      "{}: {} run(s) of revision {} are still queued in Slurm "
      "(jobs {})",
      out.string(), queued.size(), revision, job_list);
  if (force) {
    throw UsageError(what + ": cancel them first (scancel " + job_list +
                     "), so that none of them writes into the new sweep");
  }
  if (revision != MARGLAB_GIT_SHA) {
    throw UsageError(
        fmt::format("{}; this is revision {}. Wait for them (marglab sweep --status {} "
                    "--wait) or cancel them (scancel {}) before resuming, so that "
                    "one folder never mixes revisions",
                    what, MARGLAB_GIT_SHA, out.string(), job_list));
  }
  for (const PlannedRun& run : plan.runs) {
    if (queued.count(run.id) &&
        detail::readTextFile((out / "runs" / (run.id + ".cmd")).string()) != runFingerprint(run)) {
      throw UsageError(what + ": run " + run.id + " is planned differently now; cancel it first");
    }
  }
}

// The rows of the plan and the indices to submit.
std::vector<std::size_t> planRows(const SweepPlan& plan, const fs::path& out, bool resume,
                                  std::map<std::string, IndexRow> queued,
                                  std::vector<IndexRow>* rows) {
  detail::FrameEstimator frames;
  std::vector<std::size_t> queue;
  std::vector<double> weights;
  for (const PlannedRun& run : plan.runs) {
    IndexRow row = detail::plannedRow(run);
    bool other_revision = false;
    if (queued.count(run.id)) {
      row = std::move(queued[run.id]);
    } else if (!(resume && detail::keepEarlierResult(out, run, &row, &other_revision))) {
      row.set("status", "pending");
      queue.push_back(rows->size());
    }
    rows->push_back(std::move(row));
    weights.push_back(frames(run));
  }
  // Longest first: array tasks start in index order.
  std::stable_sort(queue.begin(), queue.end(),
                   [&](std::size_t a, std::size_t b) { return weights[a] > weights[b]; });
  return queue;
}

// Submits the queue and prints the arrays; false, with Slurm's message, when Slurm rejects one
// (the index then lists the runs it did not take as pending without a job: --resume submits them).
bool submitQueue(Submitter* submitter, const std::vector<std::size_t>& queue,
                 std::vector<IndexRow>* rows, const std::string& index_path, std::FILE* out,
                 std::vector<std::string>* jobs) {
  try {
    *jobs = submitter->submit(queue, rows);
  } catch (const InputError& e) {
    writeIndex(index_path, *rows);
    std::fflush(out);
    fmt::print(stderr, "marglab sweep: {}\n", e.what());
    fmt::print(out,
               "  nothing more was submitted; the folder is resumable: fix the Slurm options and "
               "run again with --resume\n");
    return false;
  }
  writeIndex(index_path, *rows);
  for (const std::string& job : submitter->describedJobs())
    fmt::print(out, "  submitted {}\n", job);
  std::fflush(out);
  return true;
}

}  // namespace

int runSlurmSweepAndReport(const SweepPlan& plan, const std::string& sweep_file,
                           const SweepOptions& options) {
  const auto start = Clock::now();
  const fs::path out = fs::absolute(options.out_dir).lexically_normal();
  std::string why;
  if (!SlurmClient::available(&why)) {
    throw UsageError("--backend slurm: no Slurm cluster answers here (" + why +
                     "); to try it on this machine: scripts/slurm_local.sh start");
  }
  // A folder another program wrote is refused whatever the flags, before anything is created.
  if (fs::exists(out / "index.csv")) detail::readOwnSweepIndex(out);
  if (!options.resume && !options.force && fs::exists(out / "index.csv")) {
    throw UsageError(fmt::format(
        "{} already holds a sweep: continue it with --resume, or start over with --force",
        out.string()));
  }
  const detail::SweepLock lock(out);
  std::map<std::string, IndexRow> queued;
  if (options.resume || options.force) queued = queuedEarlier(out);
  checkQueuedMayStay(out, plan, queued, options.force);
  detail::prepareSweepFolder(out, detail::readTextFile(sweep_file), options.resume, options.force);
  for (const char* sub : {"slurm/exit", "slurm/out"}) fs::create_directories(out / sub);
  std::vector<IndexRow> rows;
  const std::vector<std::size_t> queue =
      planRows(plan, out, options.resume, std::move(queued), &rows);
  const Provenance binary{options.executable.empty() ? fs::read_symlink("/proc/self/exe").string()
                                                     : fs::absolute(options.executable).string(),
                          MARGLAB_GIT_SHA};
  writeProvenance(out, binary);
  const std::string index_path = (out / "index.csv").string();
  writeIndex(index_path, rows);
  fmt::print(options.out, "sweep {}: {} runs -> {} (Slurm; {} to submit)\n", plan.name,
             plan.runs.size(), out.string(), queue.size());
  Submitter submitter(plan, options, out, binary);
  std::vector<std::string> jobs;
  if (!submitQueue(&submitter, queue, &rows, index_path, options.out, &jobs)) return 1;
  if (!options.slurm.wait) {
    const double wall = std::chrono::duration<double>(Clock::now() - start).count();
    if (!jobs.empty()) fmt::print(options.out, "  cancel: scancel {}\n", fmt::join(jobs, " "));
    return report(plan.name, rows, out, wall, 0, options.out);
  }
  Follower follower(plan.name, out, binary.revision, options);
  follower.alsoCancel(submitter.trackingJobs());
  const int interrupted = follower.run(&rows);
  const double wall = std::chrono::duration<double>(Clock::now() - start).count();
  return report(plan.name, rows, out, wall, interrupted, options.out);
}

int slurmSweepStatus(const std::string& dir, const SweepOptions& options) {
  const auto start = Clock::now();
  const fs::path out = fs::absolute(dir).lexically_normal();
  const std::string index_path = (out / "index.csv").string();
  readIndex(index_path);  // a folder without a sweep is refused before it is locked (created)
  const detail::SweepLock lock(out);
  std::vector<IndexRow> rows = readIndex(index_path);
  const Provenance binary = readProvenance(out);
  const std::string name = out.filename().string();
  int interrupted = 0;
  if (!binary.revision.empty()) {
    for (std::size_t i : SlurmReconciler(out, binary.revision).update(&rows)) {
      explainTrackingFailure(out, &rows[i]);
      fmt::print(options.out, "  {:<6} {}  {}\n", rows[i].get("status"), rows[i].get("id"),
                 detail::outcomeText(rows[i]));
    }
    writeIndex(index_path, rows);
    if (options.slurm.wait) interrupted = Follower(name, out, binary.revision, options).run(&rows);
  }
  for (const IndexRow& row : rows) {
    if (row.get("status") == "failed" && !detail::isFailedResult(row)) {
      fmt::print(options.out, "  failed {}  {}\n", row.get("id"), detail::outcomeText(row));
    }
  }
  const double wall = std::chrono::duration<double>(Clock::now() - start).count();
  return report(name, rows, out, wall, interrupted, options.out, !binary.revision.empty());
}

}  // namespace marglab::experiment
