// What the tables read from a results file beyond /summary (table_specs.h, readRunFileStats):
// the /sparsify statistics and the per-frame time moments of Hsiung et al.'s Tables I and II.

#include <toml++/toml.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <set>

#include "core/common/error.h"
#include "core/common/statistics.h"
#include "core/experiment/table_specs.h"
#include "core/io/results_file.h"

namespace marglab::experiment {

namespace {

Moments moments(const std::vector<double>& v) {
  Moments m;
  if (v.empty()) return m;
  m.mean = mean(v);
  double squares = 0, deviations = 0;
  for (double x : v) {
    squares += x * x;
    deviations += (x - m.mean) * (x - m.mean);
  }
  m.rmse = std::sqrt(squares / static_cast<double>(v.size()));
  m.std = std::sqrt(deviations / static_cast<double>(v.size()));
  return m;
}

int maxKeyframes(const RunInfo& info, const std::string& path) {
  try {
    const toml::table config = toml::parse(info.metadata.config_toml);
    if (const auto n = config["window"]["max_kfs"].value<std::int64_t>()) {
      return static_cast<int>(*n);
    }
  } catch (const toml::parse_error& e) {
    throw InputError(path, 0, "config_toml: " + std::string(e.description()));
  }
  throw InputError(path, 0, "config_toml has no [window] max_kfs");
}

// The frames that marginalized a keyframe. Without /sparsify rows (discard): once the window holds
// max_kfs keyframes, every new keyframe pushes one keyframe out in its own marginalization event
// (on an nfr run of MH_02_easy these frames are exactly its /sparsify frames).
std::set<std::int64_t> keyframeMarginalizations(const ResultsReader& reader,
                                                const FrameColumns& frames,
                                                const std::vector<SparsifyRecord>& events,
                                                const std::string& path) {
  std::set<std::int64_t> frames_out;
  for (const SparsifyRecord& e : events) frames_out.insert(e.frame_index);
  if (!events.empty()) return frames_out;
  const int max_kfs = maxKeyframes(reader.info(), path);
  int keyframes = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (frames.is_keyframe[i] && ++keyframes > max_kfs) {
      frames_out.insert(static_cast<std::int64_t>(i));
    }
  }
  return frames_out;
}

}  // namespace

double sampleStdOf(const std::vector<double>& v) {
  if (v.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  const double m = mean(v);
  double deviations = 0;
  for (double x : v) deviations += (x - m) * (x - m);
  return std::sqrt(deviations / static_cast<double>(v.size() - 1));
}

RunFileStats readRunFileStats(const std::string& path) {
  const ResultsReader reader(path);
  const FrameColumns frames = reader.frames();
  const std::vector<SparsifyRecord> events = reader.sparsifyRecords();
  RunFileStats s;
  s.events = static_cast<int>(events.size());
  std::vector<double> kld, ratio;
  for (const SparsifyRecord& e : events) {
    ratio.push_back(e.nnz_dense > 0
                        ? static_cast<double>(e.nnz_sparse) / static_cast<double>(e.nnz_dense)
                        : std::numeric_limits<double>::quiet_NaN());
    if (!e.recovered) continue;
    ++s.recovered;
    if (std::isfinite(e.kld)) kld.push_back(e.kld);
  }
  s.kld_mean = mean(kld);
  s.nnz_ratio = mean(ratio);
  std::vector<double> marg;
  for (const std::int64_t i : keyframeMarginalizations(reader, frames, events, path)) {
    if (i >= 0 && static_cast<std::size_t>(i) < frames.size()) {
      marg.push_back(frames.t_marg_s[static_cast<std::size_t>(i)]);
    }
  }
  s.opt = moments(frames.t_opt_s);
  s.marg = moments(marg);
  for (const MargRecord& m : reader.margs(/*with_eigenvalues=*/false)) {
    if (!std::isfinite(m.sigma_min) || !std::isfinite(m.sigma_max) || m.sigma_max <= 0) continue;
    const double ratio = m.sigma_min / m.sigma_max;
    if (!(ratio >= s.worst_sigma_ratio)) s.worst_sigma_ratio = ratio;  // NaN: the first
  }
  return s;
}

const RunFileStats& RunFileCache::of(const RunRecord& run) const {
  auto it = stats_.find(&run);
  if (it == stats_.end()) {
    it = stats_
             .emplace(&run, std::filesystem::is_regular_file(run.results_path)
                                ? readRunFileStats(run.results_path)
                                : RunFileStats{})
             .first;
  }
  return it->second;
}

}  // namespace marglab::experiment
