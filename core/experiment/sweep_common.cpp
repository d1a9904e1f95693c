#include "core/experiment/sweep_common.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>

#include "core/ba/ba_results.h"
#include "core/common/error.h"
#include "core/common/utc_time.h"
#include "core/data/sequence.h"
#include "core/estimator/variant.h"
#include "core/experiment/sweep_runner.h"
#include "core/io/results_file.h"
#include "marglab/version.h"

namespace marglab::experiment::detail {

namespace fs = std::filesystem;

std::string readTextFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return {};
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

std::string lastNonEmptyLine(const std::string& path) {
  const std::string text = readTextFile(path);
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

double FrameEstimator::operator()(const PlannedRun& run) {
  if (run.ba) {
    // A ba run's length: its iterations times the problem file's size (a proxy of its
    // observations), for the order and the ETA only.
    std::error_code ec;
    const double kb = static_cast<double>(fs::file_size(run.ba->problem, ec)) / 1e3;
    return std::max(1.0, (ec ? 1.0 : kb) * std::max(1, run.ba->options.iterations));
  }
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

namespace {

// readCompleteResults of a ba run (core/ba/ba_results.h): its root attributes. Its status
// "failed" (a linearization that cannot go on) is a numerical failure, a result; "converged",
// "max_iterations" and "no_convergence" (λ above its maximum: no further progress) are ok, the
// solver's word in ba_status.
bool readCompleteBaResults(const std::string& path, IndexRow* row, const char* git_sha,
                           bool* other_revision) {
  try {
    const BaResultsFile file = readBaResults(path);
    if (git_sha != nullptr && file.git_sha != git_sha) {
      if (other_revision != nullptr) *other_revision = true;
      return false;
    }
    const bool failed = file.status == "failed";
    row->set("status", failed ? "failed" : "ok");
    row->set("ba_status", file.status);
    row->set("failure_kind", failed ? "numerical" : "");
    row->set("reason", failed ? file.status_reason : "");
    row->setNumber("initial_cost", file.initial_cost);
    row->setNumber("final_cost", file.final_cost);
    row->setNumber("total_time_s", file.total_time_s);
    row->setNumber("peak_rss_mb", file.peak_rss_mb);
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace

bool readCompleteResults(const std::string& path, IndexRow* row, const char* git_sha,
                         bool* other_revision) {
  if (!fs::is_regular_file(path)) return false;
  if (row->get("kind") == "ba") return readCompleteBaResults(path, row, git_sha, other_revision);
  try {
    const ResultsReader reader(path, ResultsReader::Scope::kSummary);
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
    row->set("mode", reader.info().metadata.mode);
    const bool failed = status == "failed";
    row->set("failure_kind", failed ? reader.info().failure_kind : "");
    row->set("failure_frame", failed ? std::to_string(reader.info().failure_frame) : "");
    row->set("reason", failed ? reader.info().failure_reason : "");
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

bool isFailedResult(const IndexRow& row) {
  const std::string& kind = row.get("failure_kind");
  return row.get("status") == "failed" && (kind == "numerical" || kind == "tracking");
}

std::string outcomeText(const IndexRow& row) {
  if (row.get("status") == "ok") {
    if (row.get("kind") == "ba") {
      return fmt::format("cost {:.6e} ({})", row.number("final_cost"), row.get("ba_status"));
    }
    return fmt::format("ATE {:.4f} m", row.number("ate_rmse"));
  }
  const std::string& frame = row.get("failure_frame");
  return row.get("failure_kind") + (frame.empty() ? "" : " at frame " + frame) + ": " +
         row.get("reason");
}

void clearOutcome(IndexRow* row) {
  for (const char* column :
       {"failure_kind",  "failure_frame",  "reason",      "exit_code",       "signal",
        "reused",        "wall_s",         "n_frames",    "ate_rmse",        "duration_s",
        "t_opt_total_s", "t_marg_total_s", "wall_time_s", "realtime_factor", "mode",
        "pid",           "slurm_job",      "started_utc", "ba_status",       "initial_cost",
        "final_cost",    "total_time_s",   "peak_rss_mb"}) {
    row->set(column, "");
  }
}

void removeTemporaries(const fs::path& results) {
  std::error_code ec;
  const std::string prefix = results.filename().string() + ".tmp-";
  for (const auto& entry : fs::directory_iterator(results.parent_path(), ec)) {
    if (entry.path().filename().string().rfind(prefix, 0) == 0) fs::remove(entry.path(), ec);
  }
}

SweepLock::SweepLock(const fs::path& out) {
  fs::create_directories(out);
  const std::string path = (out / ".lock").string();
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) throw InputError(path, 0, std::string("cannot open the lock: ") + strerror(errno));
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    ::close(fd_);
    fd_ = -1;
    if (error != EWOULDBLOCK) {
      throw InputError(path, 0, std::string("cannot lock the sweep folder: ") + strerror(error));
    }
    std::string owner = readTextFile(path);
    owner.erase(owner.find_last_not_of(" \n") + 1);
    throw InputError(path, 0,
                     fmt::format("the sweep folder {} is in use by another marglab sweep ({}); "
                                 "wait for it to end or stop it",
                                 out.string(), owner.empty() ? "owner unknown" : owner));
  }
  char host[256] = {};
  ::gethostname(host, sizeof(host) - 1);
  const std::string owner =
      fmt::format("pid {} host {} since {}\n", ::getpid(), host, utcNowIso8601());
  // Without the owner's name the lock still holds; a second sweep then says "owner unknown".
  [[maybe_unused]] const bool named =
      ::ftruncate(fd_, 0) == 0 &&
      ::pwrite(fd_, owner.data(), owner.size(), 0) == static_cast<ssize_t>(owner.size());
}

SweepLock::~SweepLock() {
  if (fd_ >= 0) ::close(fd_);
}

std::vector<IndexRow> readOwnSweepIndex(const fs::path& out) {
  const fs::path index = out / "index.csv";
  const std::string why =
      "; marglab writes, resumes and clears (--force) only its own sweep folders: choose another "
      "--out, or move the folder's files away";
  if (!fs::is_regular_file(out / "sweep.toml")) {
    throw InputError(index.string(), 0,
                     "not a marglab sweep folder: " + (out / "sweep.toml").string() +
                         " is missing beside it" + why);
  }
  std::vector<IndexRow> rows;
  try {
    rows = readIndex(index.string());
  } catch (const InputError& e) {
    throw InputError(e.file(), e.line(), "not a marglab sweep index (" + e.detail() + ")" + why);
  }
  const std::string text = readTextFile(index.string());
  std::istringstream header(text.substr(0, text.find('\n')));
  std::set<std::string> columns;
  for (std::string column; std::getline(header, column, ',');) columns.insert(column);
  for (const char* column : {"id", "status", "results", "log", "command"}) {
    if (!columns.count(column)) {
      throw InputError(index.string(), 1,
                       fmt::format("not a marglab sweep index (no '{}' column){}", column, why));
    }
  }
  return rows;
}

namespace {

// A path the index lists, kept only when it lies in the sweep's own subfolder `sub`: an index
// that names anything else never gets it deleted.
void removeListed(const fs::path& out, const std::string& listed, const char* sub) {
  const fs::path relative = fs::path(listed).lexically_normal();
  if (listed.empty() || relative.is_absolute() || relative.begin() == relative.end() ||
      *relative.begin() != sub || relative.string().find("..") != std::string::npos) {
    return;
  }
  std::error_code ec;
  fs::remove(out / relative, ec);
}

// --force: removes what the earlier sweep wrote — the files its index lists, its track files and
// their logs, its Slurm scripts — and nothing else a user may keep in the folder.
void clearEarlierSweep(const fs::path& out, const std::vector<IndexRow>& rows) {
  for (const IndexRow& row : rows) {
    const std::string& results = row.get("results");
    removeListed(out, results, "runs");
    if (!results.empty()) {
      removeListed(out, fs::path(results).replace_extension(".tum").string(), "runs");
      removeListed(out, fs::path(results).replace_extension(".cmd").string(), "runs");
      if (fs::is_directory(out / "runs")) removeTemporaries(out / results);
    }
    removeListed(out, row.get("log"), "logs");
    removeListed(out, row.get("config"), "configs");
  }
  std::error_code ec;
  for (const char* sub : {"tracks", "logs"}) {
    for (const auto& entry : fs::directory_iterator(out / sub, ec)) {
      const std::string name = entry.path().filename().string();
      const bool written = std::string(sub) == "tracks" ? entry.path().extension() == ".h5"
                                                        : name.rfind("tracks_", 0) == 0;
      if (written) fs::remove(entry.path(), ec);
    }
  }
  fs::remove_all(out / "slurm", ec);
  fs::remove(out / "index.csv");
}

}  // namespace

void prepareSweepFolder(const fs::path& out, const std::string& sweep_file_text, bool resume,
                        bool force) {
  if (fs::exists(out / "index.csv")) {
    const std::vector<IndexRow> earlier = readOwnSweepIndex(out);
    if (!resume) {
      if (!force) {
        throw UsageError(fmt::format(
            "{} already holds a sweep: continue it with --resume, or start over with --force",
            out.string()));
      }
      clearEarlierSweep(out, earlier);
    }
  }
  for (const char* sub : {"runs", "logs", "configs"}) fs::create_directories(out / sub);
  writeFileAtomically((out / "sweep.toml").string(), sweep_file_text);
}

IndexRow plannedRow(const PlannedRun& run) {
  IndexRow row;
  row.set("id", run.id);
  row.set("group", run.group);
  row.set("dataset", run.dataset);
  row.set("variant", run.variant);
  if (run.ba) {
    // method: the elimination (ns | sc) or ceres; precision f32 | f64.
    row.set("kind", "ba");
    row.set("method", run.variant.substr(0, run.variant.find('-')));
    row.set("precision", precisionOf(run.ba->options.solver));
  } else {
    const Variant v = Variant::parse(run.variant);
    row.set("method", v.method());
    row.set("precision", v.precisionName());
  }
  row.set("seed", std::to_string(run.seed));
  row.set("frames", std::to_string(run.frames));
  row.set("override", run.override_name);
  row.set("results", "runs/" + run.id + ".h5");
  row.set("log", "logs/" + run.id + ".log");
  row.set("config", run.config_toml.empty() ? "" : "configs/" + run.id + ".toml");
  row.set("command",
          "marglab " + shellJoin(runArguments(run, row.get("results"), row.get("config"))));
  return row;
}

bool keepEarlierResult(const fs::path& out, const PlannedRun& run, IndexRow* row,
                       bool* other_revision) {
  if (readTextFile((out / "runs" / (run.id + ".cmd")).string()) != runFingerprint(run)) {
    return false;
  }
  if (!readCompleteResults((out / row->get("results")).string(), row, MARGLAB_GIT_SHA,
                           other_revision)) {
    return false;
  }
  row->set("reused", "1");
  return true;
}

void prepareRunFiles(const fs::path& out, const std::string& sweep_name, const PlannedRun& run,
                     IndexRow* row) {
  clearOutcome(row);
  const fs::path results = out / row->get("results");
  // Nothing of an earlier attempt may look like this run's result.
  std::error_code ec;
  fs::remove(results, ec);
  fs::remove(fs::path(results).replace_extension(".tum"), ec);
  removeTemporaries(results);
  if (!run.config_toml.empty()) {
    writeFileAtomically((out / row->get("config")).string(), run.config_toml);
  }
  if (!run.spec_toml.empty()) writeFileAtomically((out / runSpecFile(run)).string(), run.spec_toml);
  writeFileAtomically((out / "runs" / (run.id + ".cmd")).string(), runFingerprint(run));
  std::ofstream header(out / row->get("log"), std::ios::trunc);
  header << "# marglab sweep " << sweep_name << ": run " << run.id << "\n# started "
         << utcNowIso8601() << " in " << fs::absolute(out).string() << "\n# " << row->get("command")
         << "\n";
  if (!run.spec_toml.empty()) {
    header << "# run as: marglab " << (run.ba ? "ba" : "run") << " --spec " << runSpecFile(run)
           << "\n";
  }
}

}  // namespace marglab::experiment::detail
