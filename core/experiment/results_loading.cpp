// The runs of sweep folders for the tables (tables.h, loadResults): from each run's results file,
// or from its index row when the file is not in the folder.

#include "core/experiment/tables.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>

#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/io/results_file.h"

namespace marglab::experiment {

namespace fs = std::filesystem;

namespace {

// A run whose results file is not in the folder, from its index row: a committed sweep folder
// keeps index.csv but not runs/ (regenerated, .gitignore), and the sweep copied the row's summary
// from the file when the run ended (%.17g: the same doubles). False when the row has no outcome.
bool fromIndexRow(RunRecord* r) {
  const IndexRow& row = r->row;
  const std::string& status = row.get("status");
  if (status != "ok" && status != "failed") return false;
  if (status == "ok" && !std::isfinite(row.number("ate_rmse"))) return false;
  r->state = status == "ok" ? RunRecord::State::kOk : RunRecord::State::kFailed;
  r->mode = row.get("mode");
  r->ate_rmse = row.number("ate_rmse");
  r->t_opt_s = row.number("t_opt_total_s");
  r->t_marg_s = row.number("t_marg_total_s");
  r->wall_s = row.number("wall_time_s");
  r->duration_s = row.number("duration_s");
  const double n_frames = row.number("n_frames"), failure_frame = row.number("failure_frame");
  r->n_frames = std::isfinite(n_frames) ? static_cast<long long>(n_frames) : 0;
  r->failure_frame = std::isfinite(failure_frame) ? static_cast<long long>(failure_frame) : -1;
  return true;
}

// The dataset a run's table row is keyed by, "<kind>/<sequence>": the index holds what the sweep
// file said, which for a user's folder is its path ("/data/euroc/MH_01_easy"), so the kind and
// sequence the results file records are used; without the file, the folder's layout.
std::string tableDataset(const std::string& indexed, const RunMetadata* recorded) {
  if (recorded != nullptr && !recorded->dataset.empty() && !recorded->sequence.empty()) {
    return recorded->dataset + "/" + recorded->sequence;
  }
  if (indexed.empty() || (indexed.front() != '/' && indexed.front() != '.')) return indexed;
  try {
    const std::string folder = normalizeDatasetArgument(indexed);
    return std::string(datasetKindName(sequenceKind(folder))) + "/" +
           fs::path(folder).filename().string();
  } catch (const InputError&) {
    return indexed;  // the folder is gone: the run keeps a row of its own
  }
}

// The camera frames of a sequence (0 when it does not load), cached per name.
std::size_t cameraFrames(const std::string& name_or_path,
                         std::map<std::string, std::size_t>* cache) {
  const auto [it, fresh] = cache->emplace(name_or_path, 0);
  if (fresh) {
    try {
      it->second = loadSequence(name_or_path, LoadOptions{false}).cam_t_ns.size();
    } catch (const InputError&) {
      it->second = 0;
    }
  }
  return it->second;
}

// A run covers the whole sequence it records only when its folder holds as many frames (a
// 51-frame clip of kitti/06 is not kitti/06) and it was not cut short by `frames` = N.
void markPartialRuns(ResultSet* set) {
  std::map<std::string, std::size_t> cache;
  const std::vector<std::string> shipped = listSequences();
  for (RunRecord& r : set->runs) {
    const std::string& key = r.row.get("dataset");
    const bool named_shipped = std::find(shipped.begin(), shipped.end(), key) != shipped.end();
    const double requested = r.row.number("frames");
    const bool cut = std::isfinite(requested) && requested > 0;
    if (!named_shipped && !cut) continue;
    const std::size_t own = cameraFrames(r.indexed_dataset, &cache);
    if (own == 0) continue;
    const std::size_t whole = named_shipped ? cameraFrames(key, &cache) : own;
    const std::size_t covered = cut ? std::min(own, static_cast<std::size_t>(requested)) : own;
    if (covered < whole) r.partial_frames = static_cast<long long>(covered);
  }
}

// Two datasets recording one name keep rows of their own (the shipped one keeps the name).
void separateCollisions(ResultSet* set) {
  std::map<std::string, std::set<std::string>> indexed;
  for (const RunRecord& r : set->runs) indexed[r.row.get("dataset")].insert(r.indexed_dataset);
  for (const auto& [key, names] : indexed) {
    if (names.size() < 2) continue;
    set->warnings.push_back(fmt::format(
        "{}: runs on {} datasets record this name ({}): each keeps a row of its own, named by its "
        "folder",
        key, names.size(), fmt::join(names, ", ")));
  }
  for (RunRecord& r : set->runs) {
    const std::string key = r.row.get("dataset");
    if (indexed[key].size() > 1 && r.indexed_dataset != key) {
      r.row.set("dataset", key + " (" + r.indexed_dataset + ")");
    }
  }
}

}  // namespace

ResultSet loadResults(const std::vector<std::string>& dirs) {
  ResultSet set;
  for (const std::string& dir : dirs) {
    const std::string index = (fs::path(dir) / "index.csv").string();
    int from_index = 0;
    for (const IndexRow& row : readIndex(index)) {
      if (row.get("kind") == "ba") continue;  // `marglab ba` runs: ba_tables.h
      RunRecord r;
      r.row = row;
      r.indexed_dataset = row.get("dataset");
      r.dir = dir;
      r.results_path = (fs::path(dir) / row.get("results")).string();
      r.state =
          row.get("status") == "failed" ? RunRecord::State::kFailed : RunRecord::State::kMissing;
      const bool has_file = !row.get("results").empty() && fs::is_regular_file(r.results_path);
      if (!has_file) r.row.set("dataset", tableDataset(row.get("dataset"), nullptr));
      if (has_file) {
        try {
          const ResultsReader reader(r.results_path, ResultsReader::Scope::kSummary);
          const RunInfo& info = reader.info();
          if (info.metadata.variant != row.get("variant")) {
            throw InputError(r.results_path, 0,
                             fmt::format("variant {} but the index says {}", info.metadata.variant,
                                         row.get("variant")));
          }
          const SummaryValues s = reader.summary();
          r.row.set("dataset", tableDataset(row.get("dataset"), &info.metadata));
          r.state = info.status == "ok" ? RunRecord::State::kOk : RunRecord::State::kFailed;
          r.mode = info.metadata.mode;
          r.marg_strategy = info.metadata.marg_strategy;
          r.frontend = info.metadata.frontend;
          for (const auto& [name, value] : info.metadata.extra) {
            if (name == "gt_source") r.gt_source = value;
          }
          r.ate_rmse = s.ate_rmse;
          r.t_opt_s = s.t_opt_total_s;
          r.t_marg_s = s.t_marg_total_s;
          r.wall_s = s.wall_time_s;
          r.duration_s = s.duration_s;
          r.n_frames = s.n_frames;
          r.failure_frame = info.failure_frame;
        } catch (const InputError& e) {
          set.warnings.push_back(
              fmt::format("{}: not a complete results file ({}); counted as "
                          "not run",
                          r.results_path, e.what()));
          r.state = RunRecord::State::kMissing;
        }
      } else if (fromIndexRow(&r)) {
        ++from_index;
      } else if (row.get("status") == "ok") {
        set.warnings.push_back(r.results_path +
                               " is listed as ok but neither it nor its index row "
                               "holds an ATE; counted as not run");
      }
      set.runs.push_back(std::move(r));
    }
    if (from_index > 0) {
      set.warnings.push_back(fmt::format(
          "{}: {} run(s) read from index.csv, their results files are not in the folder", dir,
          from_index));
    }
  }
  markPartialRuns(&set);
  separateCollisions(&set);
  return set;
}

}  // namespace marglab::experiment
