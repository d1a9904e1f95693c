#include "core/experiment/sweep_runner.h"

#include <fmt/core.h>
#include <fmt/format.h>
#include <toml++/toml.h>

#include <signal.h>
#include <sys/wait.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "core/common/error.h"
#include "core/common/subprocess.h"
#include "core/common/utc_time.h"
#include "core/data/sequence.h"
#include "core/estimator/variant.h"
#include "core/experiment/slurm_backend.h"
#include "core/experiment/sweep_common.h"
#include "core/experiment/sweep_index.h"
#include "core/io/results_file.h"
#include "core/io/text_input.h"
#include "marglab/version.h"

namespace marglab::experiment {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Slot {
  std::size_t row = 0;
  Clock::time_point start;
  bool timed_out = false;
};

class Runner {
 public:
  Runner(const SweepPlan& plan, const SweepOptions& options) : plan_(plan), options_(options) {}

  SweepSummary run(const std::string& sweep_file_text) {
    const fs::path out(options_.out_dir);
    index_path_ = (out / "index.csv").string();
    const detail::SweepLock lock(out);
    prepareFolder(out, sweep_file_text);
    exe_ = options_.executable.empty() ? fs::read_symlink("/proc/self/exe").string()
                                       : options_.executable;
    jobs_ = options_.jobs > 0 ? options_.jobs : std::max(1u, std::thread::hardware_concurrency());

    // From here on SIGINT / SIGTERM wind the sweep down: the children are stopped and reaped
    // before the lock is released, so nothing writes into the folder after it.
    const StopSignals stop;
    start_ = Clock::now();
    planRows(out);
    trackImagesOnce(out);
    writeIndex(index_path_, rows_);
    loop(out);
    return finish();
  }

 private:
  void prepareFolder(const fs::path& out, const std::string& sweep_file_text) {
    detail::prepareSweepFolder(out, sweep_file_text, options_.resume, options_.force);
  }

  void planRows(const fs::path& out) {
    detail::FrameEstimator frames;
    for (const PlannedRun& run : plan_.runs) {
      IndexRow row = detail::plannedRow(run);
      bool other_revision = false;
      if (!(options_.resume && detail::keepEarlierResult(out, run, &row, &other_revision))) {
        row.set("status", "pending");
        queue_.push_back(rows_.size());
        if (other_revision) ++other_revision_;
      }
      rows_.push_back(std::move(row));
      weights_.push_back(frames(run));
    }
    // Longest first: shortens the sweep when runs differ much in length.
    std::stable_sort(queue_.begin(), queue_.end(),
                     [&](std::size_t a, std::size_t b) { return weights_[a] > weights_[b]; });
    for (std::size_t i : queue_) remaining_weight_ += weights_[i];
    queue_total_ = static_cast<int>(queue_.size());
  }

  // The image front-end once per dataset of the queued `frontend = "images"` runs, before any run
  // starts (they read its track file). A file kept by --resume is reused. A dataset whose tracking
  // fails fails its runs (they could not start); the other datasets' runs go on.
  void trackImagesOnce(const fs::path& out) {
    std::map<std::string, std::string> failed;  // track file → reason
    std::set<std::string> done;
    for (const std::size_t index : queue_) {
      const PlannedRun& run = plan_.runs[index];
      const std::string tracks = sweepTrackFile(run);
      if (run.frontend != FrontendKind::kImages || !done.insert(tracks).second) continue;
      if (options_.resume && fs::exists(out / tracks)) continue;
      const std::string reason = trackDataset(out, run.dataset, tracks);
      if (StopSignals::received() != 0) return;  // the runs stay pending for --resume
      if (!reason.empty()) failed[tracks] = reason;
    }
    if (failed.empty()) return;
    std::vector<std::size_t> startable;
    for (const std::size_t index : queue_) {
      const PlannedRun& run = plan_.runs[index];
      const auto it =
          run.frontend == FrontendKind::kImages ? failed.find(sweepTrackFile(run)) : failed.end();
      if (it == failed.end()) {
        startable.push_back(index);
        continue;
      }
      rows_[index].set("status", "failed");
      rows_[index].set("failure_kind", "error");
      rows_[index].set("reason", it->second);
      remaining_weight_ -= weights_[index];
      announce(index, 0);
    }
    queue_ = std::move(startable);
  }

  // `marglab datasets track` into <out>/<tracks>; "" when it succeeded, else why not.
  std::string trackDataset(const fs::path& out, const std::string& dataset,
                           const std::string& tracks) {
    fs::create_directories(out / "tracks");
    const fs::path log =
        fs::absolute(out / "logs" / ("tracks_" + slug(dataset) + ".log")).lexically_normal();
    fmt::print(options_.out, "tracking the images of {} -> {}\n", dataset, (out / tracks).string());
    std::fflush(options_.out);
    ChildSpec spec;
    spec.argv = {exe_, "datasets", "track", "--dataset", dataset, "-o", tracks};
    spec.working_dir = fs::absolute(out).string();
    spec.output = log.string();
    std::ofstream(log, std::ios::trunc) << "# " << shellJoin(spec.argv) << "\n";
    const ChildResult result = runChild(spec);
    if (result.stop_signal != 0) {
      fmt::print(options_.out, "tracking the images of {} interrupted ({})\n", dataset,
                 detail::signalName(result.stop_signal));
      return "interrupted";
    }
    if (result.exit_code == 0) return {};
    return fmt::format("tracking the images of {} failed (exit {}): {} (see {})", dataset,
                       result.exit_code, detail::lastNonEmptyLine(log.string()), log.string());
  }

  void launch(const fs::path& out, std::size_t index) {
    const PlannedRun& run = plan_.runs[index];
    IndexRow& row = rows_[index];
    detail::prepareRunFiles(out, plan_.name, run, &row);
    const fs::path log = out / row.get("log");

    ChildSpec spec;
    spec.argv = childArguments(run, row.get("results"), row.get("config"));
    spec.argv.insert(spec.argv.begin(), exe_);
    spec.working_dir = out.string();
    spec.output = log.string();
    // The run dies with the sweep (even a SIGKILLed one, subprocess.h), so that a --resume never
    // runs beside an orphan of the same run.
    pid_t pid = -1;
    std::string why;
    try {
      pid = startChild(spec);
    } catch (const InputError& e) {
      why = e.what();
    }
    row.set("started_utc", utcNowIso8601());
    if (pid < 0) {
      row.set("status", "failed");
      row.set("failure_kind", "error");
      row.set("reason", "cannot start the run: " + why);
      announce(index, 0);
      return;
    }
    row.set("status", "running");
    row.set("pid", std::to_string(pid));
    running_[pid] = Slot{index, Clock::now(), false};
  }

  void complete(const fs::path& out, pid_t pid, int wait_status) {
    const Slot slot = running_.at(pid);
    running_.erase(pid);
    IndexRow& row = rows_[slot.row];
    const double wall = std::chrono::duration<double>(Clock::now() - slot.start).count();
    row.setNumber("wall_s", wall);
    const fs::path results = out / row.get("results");
    detail::removeTemporaries(results);
    const std::string log = (out / row.get("log")).string();
    // A run stopped by SIGINT/SIGTERM exits 128 + signal (core/common/interrupt.h).
    const bool stopped = WIFEXITED(wait_status) && (WEXITSTATUS(wait_status) == 128 + SIGINT ||
                                                    WEXITSTATUS(wait_status) == 128 + SIGTERM);
    if (WIFSIGNALED(wait_status) || stopped) {
      const int sig = stopped ? WEXITSTATUS(wait_status) - 128 : WTERMSIG(wait_status);
      if (stopped) row.set("exit_code", std::to_string(WEXITSTATUS(wait_status)));
      row.set("signal", std::to_string(sig));
      row.set("status", "failed");
      if (slot.timed_out) {
        row.set("failure_kind", "timeout");
        row.set("reason", fmt::format("killed after the group's timeout_s ({:.0f} s)",
                                      plan_.runs[slot.row].timeout_s));
      } else if (StopSignals::received() != 0) {
        row.set("failure_kind", "interrupted");
        // The signal the sweep received (its runs are stopped with SIGTERM whatever it was).
        row.set("reason",
                "the sweep was interrupted (" + detail::signalName(StopSignals::received()) + ")");
      } else {
        row.set("failure_kind", "signal");
        row.set("reason", "killed by " + detail::signalName(sig));
      }
    } else {
      const int code = WEXITSTATUS(wait_status);
      row.set("exit_code", std::to_string(code));
      if (!detail::readCompleteResults(results.string(), &row)) {
        row.set("status", "failed");
        row.set("failure_kind", StopSignals::received() != 0 ? "interrupted" : "exit");
        row.set("reason", fmt::format("exit code {} without a complete results file: {}", code,
                                      detail::lastNonEmptyLine(log)));
      }
    }
    row.set("pid", "");
    done_weight_ += weights_[slot.row];
    done_time_ += wall;
    announce(slot.row, wall);
  }

  void announce(std::size_t index, double wall) {
    const IndexRow& row = rows_[index];
    ++finished_;
    const std::string detail = detail::outcomeText(row);
    const std::string line =
        fmt::format("[{:>{}}/{}] {:<6} {:>7.1f} s  {}  {}", finished_, digits(), queue_total_,
                    row.get("status"), wall, row.get("id"), detail);
    if (options_.status_line) fmt::print(stderr, "\r\033[K");
    fmt::print(options_.out, "{}\n", line);
    std::fflush(options_.out);
    writeIndex(index_path_, rows_);
  }

  int digits() const { return static_cast<int>(std::to_string(queue_total_).size()); }

  void statusLine() {
    if (!options_.status_line) return;
    int failed = 0;
    for (const IndexRow& row : rows_) {
      if (row.get("status") == "failed" && row.get("reused").empty()) ++failed;
    }
    const double elapsed = std::chrono::duration<double>(Clock::now() - start_).count();
    // ETA: CPU seconds per frame so far × frames left, spread over the job slots.
    double eta = std::nan("");
    if (done_weight_ > 0) {
      double left = remaining_weight_ - done_weight_;
      for (const auto& [pid, slot] : running_) {
        const double t = std::chrono::duration<double>(Clock::now() - slot.start).count();
        left -= std::min(weights_[slot.row] * 0.95, t * done_weight_ / done_time_);
      }
      eta = std::max(0.0, left) * (done_time_ / done_weight_) / jobs_;
    }
    fmt::print(stderr, "\r\033[K  sweep {}: {}/{} done, {} running, {} failed  {} elapsed  ETA {}",
               plan_.name, finished_, queue_total_, running_.size(), failed,
               detail::formatDuration(elapsed), detail::formatDuration(eta));
    std::fflush(stderr);
  }

  void loop(const fs::path& out) {
    std::size_t next = 0;
    bool stop_sent = false;
    auto last_status = Clock::now() - std::chrono::seconds(1);
    while (next < queue_.size() || !running_.empty()) {
      while (StopSignals::received() == 0 && next < queue_.size() &&
             static_cast<int>(running_.size()) < jobs_) {
        launch(out, queue_[next++]);
        writeIndex(index_path_, rows_);
      }
      if (StopSignals::received() != 0) {
        if (!stop_sent) {
          for (const auto& [pid, slot] : running_) signalChildGroup(pid, SIGTERM);
          stop_sent = true;
        }
        if (running_.empty()) break;
      }
      bool reaped = false;
      for (auto it = running_.begin(); it != running_.end();) {
        int wait_status = 0;
        const pid_t pid = it->first;
        ++it;
        const pid_t r = waitpid(pid, &wait_status, WNOHANG);
        if (r == pid) {
          complete(out, pid, wait_status);
          reaped = true;
        }
      }
      for (auto& [pid, slot] : running_) {
        const double timeout = plan_.runs[slot.row].timeout_s;
        if (timeout > 0 && !slot.timed_out &&
            std::chrono::duration<double>(Clock::now() - slot.start).count() > timeout) {
          slot.timed_out = true;
          signalChildGroup(pid, SIGKILL);
        }
      }
      if (Clock::now() - last_status > std::chrono::milliseconds(500) || reaped) {
        statusLine();
        last_status = Clock::now();
      }
      if (!reaped) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    if (options_.status_line) fmt::print(stderr, "\r\033[K");
  }

  SweepSummary finish() {
    SweepSummary s;
    s.planned = static_cast<int>(rows_.size());
    s.stop_signal = StopSignals::received();
    s.interrupted = s.stop_signal != 0;
    s.wall_s = std::chrono::duration<double>(Clock::now() - start_).count();
    s.index_path = index_path_;
    s.redone_other_revision = other_revision_;
    for (const IndexRow& row : rows_) {
      const std::string& status = row.get("status");
      if (!row.get("reused").empty()) ++s.reused;
      if (status == "ok") {
        ++s.ok;
      } else if (status == "failed") {
        s.failed.add(row);
      } else {
        ++s.not_run;
      }
    }
    writeIndex(index_path_, rows_);
    return s;
  }

  const SweepPlan& plan_;
  const SweepOptions& options_;
  std::string index_path_;
  std::string exe_;
  int jobs_ = 1;
  std::vector<IndexRow> rows_;
  std::vector<double> weights_;
  std::vector<std::size_t> queue_;
  std::map<pid_t, Slot> running_;
  int finished_ = 0;
  int other_revision_ = 0;
  int queue_total_ = 0;
  double remaining_weight_ = 0;
  double done_weight_ = 0;
  double done_time_ = 0;
  Clock::time_point start_;
};

}  // namespace

std::string shellJoin(const std::vector<std::string>& args) {
  std::string out;
  for (const std::string& a : args) {
    if (!out.empty()) out += ' ';
    const bool plain = !a.empty() && a.find_first_not_of(
                                         "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                         "0123456789_-./=:,+@%") == std::string::npos;
    if (plain) {
      out += a;
    } else {
      out += '\'';
      for (char c : a) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
      out += '\'';
    }
  }
  return out;
}

std::string runFingerprint(const PlannedRun& run) {
  const std::string config = run.config_toml.empty() ? "" : "configs/" + run.id + ".toml";
  return "marglab " + shellJoin(runArguments(run, "runs/" + run.id + ".h5", config)) + "\n" +
         run.config_toml;
}

namespace {

// --resume into the folder of another sweep would replace its index and orphan its runs.
void refuseResumingAnotherSweep(const fs::path& out, const std::string& name) {
  const fs::path recorded = out / "sweep.toml";
  if (!fs::is_regular_file(recorded)) return;
  std::string old_name;
  try {
    const toml::table root =
        toml::parse(readTextInput(recorded.string(), "the sweep file", kSettingsTextLimits));
    old_name = root["name"].value_or(std::string());
  } catch (const toml::parse_error&) {
    return;  // not ours to judge: the index check above vouched for the folder
  }
  if (!old_name.empty() && old_name != name) {
    throw UsageError(
        fmt::format("{} holds the sweep '{}', not '{}': --resume continues the same "
                    "sweep; write this one elsewhere (--out), or start over with "
                    "--force",
                    out.string(), old_name, name));
  }
}

}  // namespace

// Runs a validated plan and prints the summary; the exit code of `sweep` and `reproduce`.
int runSweepAndReport(const experiment::SweepPlan& plan, const std::string& sweep_file,
                      const experiment::SweepOptions& options) {
  if (options.backend == "slurm") return runSlurmSweepAndReport(plan, sweep_file, options);
  if (options.backend != "local") {
    throw UsageError("unknown sweep backend '" + options.backend + "' (local or slurm)");
  }
  const fs::path out(options.out_dir);
  // A folder another program wrote is refused whatever the flags, before anything is created.
  if (fs::exists(out / "index.csv")) detail::readOwnSweepIndex(out);
  if (!options.resume && !options.force && fs::exists(out / "index.csv")) {
    throw UsageError(fmt::format(
        "{} already holds a sweep: continue it with --resume, or start over with --force",
        options.out_dir));
  }
  if (options.resume) refuseResumingAnotherSweep(out, plan.name);
  const std::string text = readTextInput(sweep_file, "the sweep file", kSettingsTextLimits);
  fmt::print(options.out, "sweep {}: {} runs -> {}\n", plan.name, plan.runs.size(),
             options.out_dir);
  std::fflush(options.out);
  const experiment::SweepSummary s = experiment::runSweep(plan, text, options);
  fmt::print(options.out, "sweep {}: {} ok, {}{}{} in {:.1f} s\n", plan.name, s.ok, s.failed.text(),
             s.reused ? fmt::format(" ({} kept from an earlier invocation)", s.reused) : "",
             s.not_run ? fmt::format(", {} not run", s.not_run) : "", s.wall_s);
  if (s.redone_other_revision > 0) {
    fmt::print(options.out, "  {} complete run(s) of another git revision were run again\n",
               s.redone_other_revision);
  }
  fmt::print(options.out, "  index {}\n", s.index_path);
  if (s.interrupted) {
    fmt::print(options.out, "  interrupted by {}: continue with --resume\n",
               detail::signalName(s.stop_signal));
    return exitCodeForSignal(s.stop_signal);
  }
  // Numerical and tracking failures are results (tables show them as x); a run that ended with an
  // error, crashed or was killed is a failure of the sweep.
  return s.failed.processFailures() > 0 ? 1 : 0;
}

SweepSummary runSweep(const SweepPlan& plan, const std::string& sweep_file_text,
                      const SweepOptions& options) {
  return Runner(plan, options).run(sweep_file_text);
}

}  // namespace marglab::experiment
