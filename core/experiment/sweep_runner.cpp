#include "core/experiment/sweep_runner.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
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
#include "core/common/utc_time.h"
#include "core/data/sequence.h"
#include "core/estimator/variant.h"
#include "core/experiment/sweep_index.h"
#include "core/io/results_file.h"
#include "marglab/version.h"

namespace marglab::experiment {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

volatile std::sig_atomic_t g_stop_signal = 0;
extern "C" void onStopSignal(int signal) { g_stop_signal = signal; }

std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return {};
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

std::string lastNonEmptyLine(const std::string& path) {
  const std::string text = readFile(path);
  std::istringstream in(text);
  std::string line, last;
  while (std::getline(in, line)) {
    // A progress line overwritten with \r: keep its last state.
    const auto cr = line.find_last_of('\r');
    if (cr != std::string::npos) line = line.substr(cr + 1);
    if (line.find_first_not_of(" \t") != std::string::npos) last = line;
  }
  return last;
}

std::string signalName(int signal) {
  const char* name = sigdescr_np(signal);
  const char* abbrev = sigabbrev_np(signal);
  return fmt::format("SIG{} ({})", abbrev ? abbrev : std::to_string(signal).c_str(),
                     name ? name : "?");
}

std::string formatDuration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "--:--";
  const long s = std::lround(seconds);
  if (s >= 3600) return fmt::format("{}:{:02}:{:02}", s / 3600, (s / 60) % 60, s % 60);
  return fmt::format("{}:{:02}", s / 60, s % 60);
}

// Frames a run will process, for ordering and the ETA (the sequence length when not limited).
class FrameEstimator {
 public:
  double operator()(const PlannedRun& run) {
    double total = 0;
    auto it = cache_.find(run.dataset);
    if (it != cache_.end()) {
      total = it->second;
    } else {
      try {
        LoadOptions options;
        options.load_imu = false;
        const Sequence sequence = loadSequence(run.dataset, options);
        const auto [first, last] = framesWithinTrajectory(sequence);
        total = static_cast<double>(last > first ? last - first : sequence.cam_t_ns.size());
      } catch (const std::exception&) {
        total = 1000;  // unknown; the run itself will report the problem
      }
      cache_[run.dataset] = total;
    }
    if (run.frames > 0) total = std::min<double>(total, run.frames);
    return std::max(total, 1.0);
  }

 private:
  std::map<std::string, double> cache_;
};

// Is this a complete results file? Fills the row's summary columns when it is. With git_sha, only
// a file written by that revision counts (so --resume never mixes revisions).
bool readCompleteResults(const std::string& path, IndexRow* row, const char* git_sha = nullptr,
                         bool* other_revision = nullptr) {
  if (!fs::is_regular_file(path)) return false;
  try {
    const ResultsReader reader(path);
    if (git_sha != nullptr && reader.info().git_sha != git_sha) {
      if (other_revision != nullptr) *other_revision = true;
      return false;
    }
    const std::string& status = reader.info().status;
    if (status != "ok" && status != "failed") return false;
    const SummaryValues s = reader.summary();
    row->set("status", status);
    row->set("n_frames", std::to_string(s.n_frames));
    row->setNumber("ate_rmse", s.ate_rmse);
    row->setNumber("duration_s", s.duration_s);
    row->setNumber("t_opt_total_s", s.t_opt_total_s);
    row->setNumber("t_marg_total_s", s.t_marg_total_s);
    row->setNumber("wall_time_s", s.wall_time_s);
    row->setNumber("realtime_factor", s.realtime_factor);
    if (status == "failed") {
      row->set("failure_kind", "numerical");
      row->set("failure_frame", std::to_string(reader.info().failure_frame));
      row->set("reason", reader.info().failure_reason);
    } else {
      row->set("failure_kind", "");
      row->set("failure_frame", "");
      row->set("reason", "");
    }
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

void clearOutcome(IndexRow* row) {
  for (const char* column :
       {"failure_kind", "failure_frame", "reason", "exit_code", "signal", "reused", "wall_s",
        "n_frames", "ate_rmse", "duration_s", "t_opt_total_s", "t_marg_total_s", "wall_time_s",
        "realtime_factor", "pid", "started_utc"}) {
    row->set(column, "");
  }
}

// Removes what a killed writer may leave behind: <results>.tmp-<pid>-<n>.
void removeTemporaries(const fs::path& results) {
  std::error_code ec;
  const std::string prefix = results.filename().string() + ".tmp-";
  for (const auto& entry : fs::directory_iterator(results.parent_path(), ec)) {
    if (entry.path().filename().string().rfind(prefix, 0) == 0) fs::remove(entry.path(), ec);
  }
}

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
    prepareFolder(out, sweep_file_text);
    exe_ = options_.executable.empty() ? fs::read_symlink("/proc/self/exe").string()
                                       : options_.executable;
    jobs_ = options_.jobs > 0 ? options_.jobs : std::max(1u, std::thread::hardware_concurrency());

    planRows(out);
    trackImagesOnce(out);
    writeIndex(index_path_, rows_);
    installSignalHandlers();
    start_ = Clock::now();
    loop(out);
    restoreSignalHandlers();
    return finish();
  }

 private:
  void prepareFolder(const fs::path& out, const std::string& sweep_file_text) {
    if (fs::exists(out / "index.csv") && !options_.resume) {
      if (!options_.force) {
        throw UsageError(fmt::format(
            "{} already holds a sweep: continue it with --resume, or start over with --force",
            out.string()));
      }
      for (const char* sub : {"runs", "logs", "configs", "tracks"}) fs::remove_all(out / sub);
      fs::remove(out / "index.csv");
    }
    for (const char* sub : {"runs", "logs", "configs"}) fs::create_directories(out / sub);
    writeFileAtomically((out / "sweep.toml").string(), sweep_file_text);
  }

  void planRows(const fs::path& out) {
    FrameEstimator frames;
    for (const PlannedRun& run : plan_.runs) {
      IndexRow row;
      row.set("id", run.id);
      row.set("group", run.group);
      row.set("dataset", run.dataset);
      row.set("variant", run.variant);
      const Variant v = Variant::parse(run.variant);
      row.set("method", v.method());
      row.set("precision", v.precision == Precision::kF32 ? "f32" : "f64");
      row.set("seed", std::to_string(run.seed));
      row.set("frames", std::to_string(run.frames));
      row.set("override", run.override_name);
      row.set("results", "runs/" + run.id + ".h5");
      row.set("log", "logs/" + run.id + ".log");
      row.set("config", run.config_toml.empty() ? "" : "configs/" + run.id + ".toml");
      row.set("command",
              "marglab " + shellJoin(runArguments(run, row.get("results"), row.get("config"))));
      const std::string fingerprint = runFingerprint(run);
      const std::string results = (out / row.get("results")).string();
      bool other_revision = false;
      if (options_.resume && readFile((out / "runs" / (run.id + ".cmd")).string()) == fingerprint &&
          readCompleteResults(results, &row, MARGLAB_GIT_SHA, &other_revision)) {
        row.set("reused", "1");
      } else {
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
  }

  // The image front-end once per dataset of the queued `frontend = "images"` runs, before any run
  // starts (they read its track file). A file kept by --resume is reused.
  void trackImagesOnce(const fs::path& out) {
    std::set<std::string> done;
    for (const std::size_t index : queue_) {
      const PlannedRun& run = plan_.runs[index];
      const std::string tracks = sweepTrackFile(run);
      if (run.frontend != "images" || !done.insert(tracks).second) continue;
      if (options_.resume && fs::exists(out / tracks)) continue;
      fs::create_directories(out / "tracks");
      const std::string log = (out / "logs" / ("tracks_" + slug(run.dataset) + ".log")).string();
      const std::string command =
          "cd " + shellJoin({out.string()}) + " && " +
          shellJoin({exe_, "datasets", "track", "--dataset", run.dataset, "-o", tracks}) + " > " +
          shellJoin({log}) + " 2>&1";
      if (std::system(command.c_str()) != 0) {
        throw InputError(
            log, 0, fmt::format("tracking the images of {} failed (see the log)", run.dataset));
      }
    }
  }

  void launch(const fs::path& out, std::size_t index) {
    const PlannedRun& run = plan_.runs[index];
    IndexRow& row = rows_[index];
    clearOutcome(&row);
    const fs::path results = out / row.get("results");
    const fs::path log = out / row.get("log");
    // Nothing of an earlier attempt may look like this run's result.
    std::error_code ec;
    fs::remove(results, ec);
    fs::remove(fs::path(results).replace_extension(".tum"), ec);
    removeTemporaries(results);
    if (!run.config_toml.empty()) {
      writeFileAtomically((out / row.get("config")).string(), run.config_toml);
    }
    writeFileAtomically((out / "runs" / (run.id + ".cmd")).string(), runFingerprint(run));
    {
      std::ofstream header(log, std::ios::trunc);
      header << "# marglab sweep " << plan_.name << ": run " << run.id << "\n# started "
             << utcNowIso8601() << " in " << fs::absolute(out).string() << "\n# "
             << row.get("command") << "\n";
    }

    std::vector<std::string> args = runArguments(run, row.get("results"), row.get("config"));
    args.insert(args.begin(), exe_);
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const std::string dir = out.string();
    const std::string log_path = log.string();

    std::fflush(nullptr);
    const pid_t pid = fork();
    if (pid == 0) {
      // Child: only async-signal-safe calls from here on.
      signal(SIGINT, SIG_DFL);
      signal(SIGTERM, SIG_DFL);
      const int fd = open(log_path.c_str(), O_WRONLY | O_APPEND | O_CREAT, 0644);
      const int null_fd = open("/dev/null", O_RDONLY);
      if (fd < 0 || null_fd < 0 || chdir(dir.c_str()) != 0) _exit(126);
      dup2(null_fd, STDIN_FILENO);
      dup2(fd, STDOUT_FILENO);
      dup2(fd, STDERR_FILENO);
      close(fd);
      close(null_fd);
      execv(argv[0], argv.data());
      const char message[] = "marglab sweep: exec of the marglab binary failed\n";
      [[maybe_unused]] const ssize_t n = write(STDERR_FILENO, message, sizeof(message) - 1);
      _exit(127);
    }
    row.set("started_utc", utcNowIso8601());
    if (pid < 0) {
      row.set("status", "failed");
      row.set("failure_kind", "error");
      row.set("reason", std::string("cannot start the run: fork failed: ") + std::strerror(errno));
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
    removeTemporaries(results);
    const std::string log = (out / row.get("log")).string();
    if (WIFSIGNALED(wait_status)) {
      const int sig = WTERMSIG(wait_status);
      row.set("signal", std::to_string(sig));
      row.set("status", "failed");
      if (slot.timed_out) {
        row.set("failure_kind", "timeout");
        row.set("reason", fmt::format("killed after the group's timeout_s ({:.0f} s)",
                                      plan_.runs[slot.row].timeout_s));
      } else if (g_stop_signal != 0) {
        row.set("failure_kind", "interrupted");
        row.set("reason", "the sweep was interrupted (" + signalName(sig) + ")");
      } else {
        row.set("failure_kind", "signal");
        row.set("reason", "killed by " + signalName(sig));
      }
    } else {
      const int code = WEXITSTATUS(wait_status);
      row.set("exit_code", std::to_string(code));
      if (!readCompleteResults(results.string(), &row)) {
        row.set("status", "failed");
        row.set("failure_kind", g_stop_signal != 0 ? "interrupted" : "exit");
        row.set("reason", fmt::format("exit code {} without a complete results file: {}", code,
                                      lastNonEmptyLine(log)));
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
    std::string detail;
    if (row.get("status") == "ok") {
      detail = fmt::format("ATE {:.4f} m", row.number("ate_rmse"));
    } else {
      const std::string& frame = row.get("failure_frame");
      detail = row.get("failure_kind") + (frame.empty() ? "" : " at frame " + frame) + ": " +
               row.get("reason");
    }
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
               formatDuration(elapsed), formatDuration(eta));
    std::fflush(stderr);
  }

  void loop(const fs::path& out) {
    std::size_t next = 0;
    queue_total_ = static_cast<int>(queue_.size());
    bool stop_sent = false;
    auto last_status = Clock::now() - std::chrono::seconds(1);
    while (next < queue_.size() || !running_.empty()) {
      while (g_stop_signal == 0 && next < queue_.size() &&
             static_cast<int>(running_.size()) < jobs_) {
        launch(out, queue_[next++]);
        writeIndex(index_path_, rows_);
      }
      if (g_stop_signal != 0) {
        if (!stop_sent) {
          for (const auto& [pid, slot] : running_) kill(pid, SIGTERM);
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
          kill(pid, SIGKILL);
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
    s.interrupted = g_stop_signal != 0;
    s.wall_s = std::chrono::duration<double>(Clock::now() - start_).count();
    s.index_path = index_path_;
    s.redone_other_revision = other_revision_;
    for (const IndexRow& row : rows_) {
      const std::string& status = row.get("status");
      if (!row.get("reused").empty()) ++s.reused;
      if (status == "ok") {
        ++s.ok;
      } else if (status == "failed") {
        (row.get("failure_kind") == "numerical" ? s.failed_numerical : s.failed_process)++;
      } else {
        ++s.not_run;
      }
    }
    writeIndex(index_path_, rows_);
    return s;
  }

  void installSignalHandlers() {
    g_stop_signal = 0;
    struct sigaction action {};
    action.sa_handler = onStopSignal;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &old_int_);
    sigaction(SIGTERM, &action, &old_term_);
  }
  void restoreSignalHandlers() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
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
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
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

// Runs a validated plan and prints the summary; the exit code of `sweep` and `reproduce`.
int runSweepAndReport(const experiment::SweepPlan& plan, const std::string& sweep_file,
                      const experiment::SweepOptions& options) {
  if (!options.resume && !options.force && fs::exists(fs::path(options.out_dir) / "index.csv")) {
    throw UsageError(fmt::format(
        "{} already holds a sweep: continue it with --resume, or start over with --force",
        options.out_dir));
  }
  std::ifstream in(sweep_file);
  std::stringstream text;
  text << in.rdbuf();
  fmt::print(options.out, "sweep {}: {} runs -> {}\n", plan.name, plan.runs.size(),
             options.out_dir);
  std::fflush(options.out);
  const experiment::SweepSummary s = experiment::runSweep(plan, text.str(), options);
  fmt::print(options.out,
             "sweep {}: {} ok, {} failed numerically, {} crashed or killed{}{} in {:.1f} s\n",
             plan.name, s.ok, s.failed_numerical, s.failed_process,
             s.reused ? fmt::format(" ({} kept from an earlier invocation)", s.reused) : "",
             s.not_run ? fmt::format(", {} not run", s.not_run) : "", s.wall_s);
  if (s.redone_other_revision > 0) {
    fmt::print(options.out, "  {} complete run(s) of another git revision were run again\n",
               s.redone_other_revision);
  }
  fmt::print(options.out, "  index {}\n", s.index_path);
  if (s.interrupted) {
    fmt::print(options.out, "  interrupted: continue with --resume\n");
    return 130;
  }
  // Numerical failures are results (tables show them as x); a run that crashed is an error.
  return s.failed_process > 0 ? 1 : 0;
}

SweepSummary runSweep(const SweepPlan& plan, const std::string& sweep_file_text,
                      const SweepOptions& options) {
  return Runner(plan, options).run(sweep_file_text);
}

}  // namespace marglab::experiment
