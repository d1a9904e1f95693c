// Tables from loaded runs (tables.h, buildTables): which runs fill which cell, the seed
// statistics of a cell, the best value of a row, the papers' values beside ours.

#include "core/experiment/tables.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <toml++/toml.h>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <set>
#include <tuple>
#include <utility>

#include "core/common/error.h"
#include "core/estimator/marg_prior.h"
#include "core/estimator/variant.h"
#include "core/io/results_file.h"

namespace marglab::experiment {

namespace {

namespace fs = std::filesystem;

const std::vector<std::string> kHeadline = {"ns-qr-sqrt-f64", "ns-qr-sqrt-f32", "sc-sc-sq-f64",
                                            "sc-sc-sq-f32"};
const std::string kMixed = "ns-qr-sqrt-mixed";
// Beside the preconditioned storages: the paper's √-f32 and SC-32, and the square root of an
// unpreconditioned LDLT (what sqrtp preconditions).
const std::vector<std::string> kPreconditionedReferences = {"ns-qr-sqrt-f32", "sc-sc-sq-f32",
                                                            "sc-sc-sqrt-f32"};
// The preconditioned variants' columns in this order (others after them, by name).
const std::vector<std::string> kPreconditionedOrder = {"sc-sc-sqp-f32", "ns-sc-sqp-f32",
                                                       "sc-sc-sqj-f32", "sc-sc-sqrtp-f32",
                                                       "sc-sc-sqp-f64"};
const char* const kSeedNote =
    "Seeds: mean ± sample standard deviation of the ATE over the seeds whose run finished ok; "
    "`x k/n`: k of the n finished seeds failed (left out of the mean); the paper's value is one "
    "run.";
const std::vector<std::string> kAblation = {"ns-qr-sqrt-f64", "ns-qr-sqrt-f32", "sc-qr-sqrt-f64",
                                            "sc-qr-sqrt-f32", "ns-sc-sqrt-f64", "ns-sc-sqrt-f32",
                                            "sc-sc-sqrt-f64", "sc-sc-sqrt-f32"};

bool startsWith(const std::string& s, const std::string& prefix) { return s.rfind(prefix, 0) == 0; }
bool isVioDataset(const std::string& d) {
  return startsWith(d, "euroc/") || startsWith(d, "tumvi/");
}
bool isVoDataset(const std::string& d) { return startsWith(d, "kitti/"); }
bool isEurocDataset(const std::string& d) { return startsWith(d, "euroc/"); }

// Hsiung et al.'s order of columns: theirs (nfr), the dense prior it sparsifies, OKVIS's (discard).
const std::vector<std::string> kStrategies = {"nfr", "dense", "discard"};

std::vector<TableColumn> headlineColumns(const std::string& family) {
  std::vector<TableColumn> columns;
  for (const std::string& v : kHeadline) {
    const bool sqrt = startsWith(v, "ns-qr-sqrt");
    const std::string bits = v.substr(v.size() - 2);
    columns.push_back({v, fmt::format("{}{}-{}", sqrt ? "√" : "", family, bits),
                       sqrt ? fmt::format("$\\sqrt{{\\text{{{}}}}}$-{}", family, bits)
                            : fmt::format("\\textit{{{}-{}}}", family, bits),
                       -1, ""});
  }
  return columns;
}

std::vector<TableColumn> ablationColumns() {
  std::vector<TableColumn> columns;
  for (const std::string& v : kAblation) {
    // ns-qr-sqrt-f64 → "NS/QR-64": optimization NS+LDLT or SC+LDLT, marginalization NS+QR or SC+SC.
    std::string opt = v.substr(0, 2), marg = v.substr(3, 2);
    for (auto* s : {&opt, &marg}) std::transform(s->begin(), s->end(), s->begin(), ::toupper);
    const std::string label = fmt::format("{}/{}-{}", opt, marg, v.substr(v.size() - 2));
    columns.push_back({v, label, label, -1, ""});
  }
  return columns;
}

double mean(const std::vector<double>& v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  double s = 0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

double roundTo(double v, int decimals) {
  const double scale = std::pow(10.0, decimals);
  return std::round(v * scale) / scale;
}

// Marks the best value(s) of a row per quantity, compared as printed.
// Only the first `ranked` cells compete (the others are columns of another quantity).
void markBest(std::vector<TableCell>& cells, std::size_t quantities, int decimals, bool higher,
              std::size_t ranked = std::numeric_limits<std::size_t>::max()) {
  for (auto& cell : cells) cell.best.assign(quantities, false);
  const auto end = cells.begin() + static_cast<std::ptrdiff_t>(std::min(ranked, cells.size()));
  for (std::size_t q = 0; q < quantities; ++q) {
    double best =
        higher ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
    bool any = false;
    for (auto it = cells.begin(); it != end; ++it) {
      const TableCell& cell = *it;
      if (cell.state != TableCell::State::kValue || !std::isfinite(cell.numbers[q])) continue;
      const double r = roundTo(cell.numbers[q], decimals);
      best = higher ? std::max(best, r) : std::min(best, r);
      any = true;
    }
    if (!any) continue;
    for (auto it = cells.begin(); it != end; ++it) {
      TableCell& cell = *it;
      if (cell.state == TableCell::State::kValue && std::isfinite(cell.numbers[q]) &&
          roundTo(cell.numbers[q], decimals) == best) {
        cell.best[q] = true;
      }
    }
  }
}

TableCell paperCell(const PaperTable* table, const std::string& row_key, const std::string& variant,
                    const std::vector<std::string>& quantities) {
  TableCell cell;
  if (table == nullptr) return cell;
  const PaperTable::Row* row = table->row(row_key);
  const auto col = std::find(table->columns.begin(), table->columns.end(), variant);
  if (row == nullptr || col == table->columns.end()) return cell;
  const std::size_t c = static_cast<std::size_t>(col - table->columns.begin());
  cell.state = TableCell::State::kValue;
  for (const std::string& q : quantities) {
    const auto it = row->cells.find(q);
    if (it == row->cells.end()) return TableCell{};
    const PaperCell& p = it->second[c];
    if (p.state == PaperCell::State::kFailed) {
      cell.state = TableCell::State::kFailed;
      cell.numbers.clear();
      return cell;
    }
    if (p.state == PaperCell::State::kMissing) return TableCell{};
    cell.numbers.push_back(p.value);
  }
  return cell;
}

// The runs of one dataset × variant (all seeds) of the selected override.
struct Selection {
  std::vector<const RunRecord*> runs;
  TableCell::State state() const {
    if (runs.empty()) return TableCell::State::kMissing;
    bool missing = false;
    for (const RunRecord* r : runs) {
      if (r->state == RunRecord::State::kFailed) return TableCell::State::kFailed;
      if (r->state != RunRecord::State::kOk) missing = true;
    }
    return missing ? TableCell::State::kMissing : TableCell::State::kValue;
  }
};

// A cell of ours: the mean over the selection's runs (seeds) of each quantity.
using RunValue = std::function<double(const RunRecord&)>;
TableCell meanCell(const Selection& sel, const std::vector<RunValue>& quantities) {
  TableCell cell;
  cell.state = sel.state();
  cell.n_runs = static_cast<int>(sel.runs.size());
  if (cell.state != TableCell::State::kValue) return cell;
  for (const RunValue& value : quantities) {
    std::vector<double> v;
    for (const RunRecord* r : sel.runs) v.push_back(value(*r));
    cell.numbers.push_back(mean(v));
  }
  return cell;
}

// Sample standard deviation (n − 1); NaN for fewer than two values.
double sampleStd(const std::vector<double>& v) {
  if (v.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  const double m = mean(v);
  double deviations = 0;
  for (double x : v) deviations += (x - m) * (x - m);
  return std::sqrt(deviations / static_cast<double>(v.size() - 1));
}

// A cell of ours with seed statistics (TableCell::seed_stats): the ok seeds give the mean and
// spread, the failed ones the count; unfinished runs are left out.
TableCell seedCell(const Selection& sel, const std::vector<RunValue>& quantities) {
  TableCell cell;
  cell.seed_stats = true;
  std::vector<const RunRecord*> ok;
  for (const RunRecord* r : sel.runs) {
    if (r->state == RunRecord::State::kOk) ok.push_back(r);
    if (r->state == RunRecord::State::kFailed) ++cell.n_failed;
  }
  cell.n_runs = static_cast<int>(ok.size()) + cell.n_failed;
  if (cell.n_runs == 0) return cell;
  if (ok.empty()) {
    cell.state = TableCell::State::kFailed;
    return cell;
  }
  cell.state = TableCell::State::kValue;
  for (const RunValue& value : quantities) {
    std::vector<double> v;
    for (const RunRecord* r : ok) v.push_back(value(*r));
    cell.numbers.push_back(mean(v));
    cell.spread.push_back(sampleStd(v));
  }
  return cell;
}

// A cell of the frames where the failed runs of a selection stopped: their median (kMissing, "–",
// when none failed).
TableCell failureFrameCell(const Selection& sel) {
  TableCell cell;
  std::vector<double> frames;
  for (const RunRecord* r : sel.runs) {
    if (r->state == RunRecord::State::kFailed && r->failure_frame >= 0) {
      frames.push_back(static_cast<double>(r->failure_frame));
    }
  }
  cell.n_runs = static_cast<int>(frames.size());
  if (frames.empty()) return cell;
  std::sort(frames.begin(), frames.end());
  const std::size_t n = frames.size();
  cell.state = TableCell::State::kValue;
  cell.numbers = {n % 2 == 1 ? frames[n / 2] : 0.5 * (frames[n / 2 - 1] + frames[n / 2])};
  return cell;
}

// A variant whose prior storage is preconditioned (sqp, sqj, sqrtp: docs/preconditioned_storage.md).
bool isPreconditioned(const std::string& variant) {
  try {
    return preconditioningOf(Variant::parse(variant).storage) != Preconditioning::kNone;
  } catch (const UsageError&) {
    return false;
  }
}

struct Moments {
  double mean = std::numeric_limits<double>::quiet_NaN();
  double rmse = std::numeric_limits<double>::quiet_NaN();
  double std = std::numeric_limits<double>::quiet_NaN();  // population, as RMSE² = mean² + std²
};

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

// What the strategy tables read from one results file beyond /summary.
struct StrategyStats {
  double kld_mean = std::numeric_limits<double>::quiet_NaN();   // over recovered /sparsify rows
  double nnz_ratio = std::numeric_limits<double>::quiet_NaN();  // mean over all /sparsify rows
  int events = 0, recovered = 0;
  Moments opt;   // /frames t_opt_s, every frame
  Moments marg;  // /frames t_marg_s of the frames that marginalized a keyframe
};

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

StrategyStats readStrategyStats(const std::string& path) {
  const ResultsReader reader(path);
  const FrameColumns frames = reader.frames();
  const std::vector<SparsifyRecord> events = reader.sparsifyRecords();
  StrategyStats s;
  s.events = static_cast<int>(events.size());
  std::vector<double> kld, ratio;
  std::set<std::int64_t> keyframe_marg;
  for (const SparsifyRecord& e : events) {
    keyframe_marg.insert(e.frame_index);
    ratio.push_back(e.nnz_dense > 0
                        ? static_cast<double>(e.nnz_sparse) / static_cast<double>(e.nnz_dense)
                        : std::numeric_limits<double>::quiet_NaN());
    if (!e.recovered) continue;
    ++s.recovered;
    if (std::isfinite(e.kld)) kld.push_back(e.kld);
  }
  s.kld_mean = mean(kld);
  s.nnz_ratio = mean(ratio);
  if (events.empty()) {
    // No /sparsify rows (discard): once the window holds max_kfs keyframes, every new keyframe
    // pushes one keyframe out in its own marginalization event (on an nfr run of MH_02_easy these
    // frames are exactly its /sparsify frames).
    const int max_kfs = maxKeyframes(reader.info(), path);
    int keyframes = 0;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      if (frames.is_keyframe[i] && ++keyframes > max_kfs) {
        keyframe_marg.insert(static_cast<std::int64_t>(i));
      }
    }
  }
  std::vector<double> marg;
  for (const std::int64_t i : keyframe_marg) {
    if (i >= 0 && static_cast<std::size_t>(i) < frames.size()) {
      marg.push_back(frames.t_marg_s[static_cast<std::size_t>(i)]);
    }
  }
  s.opt = moments(frames.t_opt_s);
  s.marg = moments(marg);
  return s;
}

// The column a run belongs to in a table set (its variant, or its marginalization strategy);
// nullopt: not part of the set.
using ColumnOf = std::function<std::optional<std::string>(const RunRecord&)>;

// frontends: where the runs' tracks came from (results file attribute "frontend").
std::string oursNote(const std::string& paper_machine, const std::set<std::string>& frontends) {
  std::vector<std::string> sources;
  for (const std::string& f : frontends) {
    sources.push_back(f == "images"   ? "the image front-end on the real images"
                      : f == "tracks" ? "track files (--tracks)"
                                      : "simulated stereo tracks along the real trajectories");
  }
  if (sources.empty()) sources.push_back("simulated stereo tracks along the real trajectories");
  return fmt::format("Ours: {}, `frames` = frames per run (`all`: the whole sequence); the "
                     "paper: real images, whole sequences{}",
                     fmt::join(sources, "; "),
                     paper_machine.empty() ? std::string(".") : ", on " + paper_machine + ".");
}

// A cell of a table set: a dataset (row) and a column (variant or strategy); with the seed, one run.
struct CellKey {
  std::string dataset, column;
  bool operator<(const CellKey& o) const {
    return std::tie(dataset, column) < std::tie(o.dataset, o.column);
  }
};
struct RunKey {
  CellKey cell;
  std::string seed;
  bool operator<(const RunKey& o) const { return std::tie(cell, seed) < std::tie(o.cell, o.seed); }
};

class Builder {
 public:
  Builder(const ResultSet& results, const PaperValues& paper, const ColumnOf& column_of)
      : paper_(paper) {
    // Deduplicate dataset × column × seed: the run with more requested frames wins.
    std::map<RunKey, const RunRecord*> chosen;
    for (const RunRecord& r : results.runs) {
      const std::optional<std::string> column = column_of(r);
      if (!column) continue;
      const RunKey key{{r.row.get("dataset"), *column}, r.row.get("seed")};
      auto frames = [](const RunRecord* x) {
        const double f = x->row.number("frames");
        return !std::isfinite(f) || f <= 0 ? std::numeric_limits<double>::infinity() : f;
      };
      auto it = chosen.find(key);
      if (it == chosen.end() || frames(&r) > frames(it->second)) chosen[key] = &r;
    }
    for (const auto& [key, run] : chosen) {
      by_cell_[key.cell].runs.push_back(run);
      datasets_.insert(run->row.get("dataset"));
      modes_[run->row.get("dataset")].insert(run->mode.empty() ? "?" : run->mode);
      if (!run->frontend.empty()) frontends_[run->row.get("dataset")].insert(run->frontend);
    }
  }

  // Where the tracks of these datasets' runs came from (results file attribute "frontend").
  std::set<std::string> frontendsOf(const std::vector<std::string>& datasets) const {
    std::set<std::string> all;
    for (const std::string& d : datasets) {
      const auto it = frontends_.find(d);
      if (it != frontends_.end()) all.insert(it->second.begin(), it->second.end());
    }
    return all;
  }

  bool hasVariant(const std::string& variant) const {
    return std::any_of(by_cell_.begin(), by_cell_.end(),
                       [&variant](const auto& cell) { return cell.first.column == variant; });
  }

  const Selection& select(const std::string& dataset, const std::string& variant) const {
    static const Selection kNone;
    const auto it = by_cell_.find(CellKey{dataset, variant});
    return it == by_cell_.end() ? kNone : it->second;
  }

  // Datasets of a family, in the paper's row order, then the others by name.
  std::vector<std::string> rowsFor(bool (*family)(const std::string&), const PaperTable* table,
                                   const std::vector<std::string>& variants) const {
    std::vector<std::string> rows;
    auto present = [&](const std::string& d) {
      return std::any_of(variants.begin(), variants.end(),
                         [&](const std::string& v) { return !select(d, v).runs.empty(); });
    };
    if (table != nullptr) {
      for (const auto& row : table->rows) {
        if (datasets_.count(row.key) && present(row.key)) rows.push_back(row.key);
      }
    }
    for (const std::string& d : datasets_) {
      if (family(d) && present(d) && std::find(rows.begin(), rows.end(), d) == rows.end()) {
        rows.push_back(d);
      }
    }
    return rows;
  }

  std::string framesLabel(const std::string& dataset,
                          const std::vector<std::string>& variants) const {
    double most = 0;
    for (const std::string& v : variants) {
      for (const RunRecord* r : select(dataset, v).runs) {
        const double f = r->row.number("frames");
        if (!std::isfinite(f) || f <= 0) return "all";
        most = std::max(most, f);
      }
    }
    return most > 0 ? fmt::format("{:.0f}", most) : "";
  }

  std::string rowLabel(const PaperTable* table, const std::string& dataset, bool* estimate) const {
    std::string label = dataset;
    if (table != nullptr) {
      if (const PaperTable::Row* row = table->row(dataset)) label = row->label;
    }
    for (const auto& [key, sel] : by_cell_) {
      if (key.dataset != dataset) continue;
      for (const RunRecord* r : sel.runs) {
        if (r->gt_source.find("estimate") != std::string::npos) {
          *estimate = true;
          return label + "*";
        }
      }
    }
    return label;
  }

  // The estimator modes of the runs of these datasets (the tables do not assume VIO has landed).
  std::string modeNote(const std::vector<std::string>& datasets) const {
    std::set<std::string> set;
    for (const std::string& d : datasets) {
      const auto it = modes_.find(d);
      if (it != modes_.end()) set.insert(it->second.begin(), it->second.end());
    }
    std::vector<std::string> modes(set.begin(), set.end());
    return fmt::format("Estimator mode of our runs (results attribute `mode`): {}.",
                       fmt::join(modes, ", "));
  }

  // Whether a cell of Table 1 (vio) or 2 holds more than one seed.
  bool severalSeeds(bool vio) const {
    for (const auto& [key, sel] : by_cell_) {
      if ((vio ? isVioDataset : isVoDataset)(key.dataset) && sel.runs.size() > 1) return true;
    }
    return false;
  }

  // Tables 1, 2 (ATE; with seed statistics when seed_stats) and 3, 5 (runtime).
  std::optional<Table> perSequence(int number, bool vio, bool seed_stats = false) const {
    const std::string id = fmt::format("table{}", number);
    const PaperTable* paper = paperTable(id);
    const bool ate = number == 1 || number == 2;
    Table t;
    t.id = id;
    t.title = ate ? fmt::format("Table {}: absolute trajectory error [m], {}", number,
                                vio ? "VIO (EuRoC, TUM-VI)" : "VO (KITTI)")
                  : fmt::format("Table {}: runtime [s], optimization / marginalization, {}", number,
                                vio ? "VIO (EuRoC, TUM-VI)" : "VO (KITTI)");
    t.row_header = "sequence";
    t.quantities = ate ? std::vector<std::string>{"ate"} : std::vector<std::string>{"opt", "marg"};
    t.columns = headlineColumns(vio ? "VIO" : "VO");
    // The mixed-precision variant (not in the paper) joins as an extra column when it was run.
    if (hasVariant(kMixed)) {
      const std::string family = vio ? "VIO" : "VO";
      t.columns.push_back({kMixed, fmt::format("√{}-mixed", family),
                           fmt::format("$\\sqrt{{\\text{{{}}}}}$-mixed", family), -1, ""});
    }
    const RunValue ate_m = [](const RunRecord& r) { return r.ate_rmse; };
    const std::vector<RunValue> runtime = {[](const RunRecord& r) { return r.t_opt_s; },
                                           [](const RunRecord& r) { return r.t_marg_s; }};
    bool any_estimate = false;
    for (const std::string& dataset : rowsFor(vio ? isVioDataset : isVoDataset, paper, kHeadline)) {
      TableRow row;
      row.key = dataset;
      row.label = rowLabel(paper, dataset, &any_estimate);
      row.frames = framesLabel(dataset, kHeadline);
      row.ours_decimals = ate ? 4 : 2;
      row.paper_decimals = ate ? (vio ? 3 : 2) : 1;
      const std::vector<RunValue> quantities = ate ? std::vector<RunValue>{ate_m} : runtime;
      for (const TableColumn& column : t.columns) {
        const Selection& runs = select(dataset, column.variant);
        row.ours.push_back(seed_stats && ate ? seedCell(runs, quantities)
                                             : meanCell(runs, quantities));
        row.paper.push_back(paperCell(paper, dataset, column.variant, t.quantities));
      }
      markBest(row.ours, t.quantities.size(), row.ours_decimals, false);
      markBest(row.paper, t.quantities.size(), row.paper_decimals, false);
      t.rows.push_back(std::move(row));
    }
    if (t.rows.empty()) return std::nullopt;
    t.notes.push_back(
        ate ? "ATE: RMSE of the positions after SE(3) alignment to the reference, in metres "
              "(results /summary ate_rmse)."
            : "Total wall time of optimization / marginalization in seconds (results /summary "
              "t_opt_total_s / t_marg_total_s); diagnostics are not timed.");
    std::vector<std::string> keys;
    for (const TableRow& r : t.rows) keys.push_back(r.key);
    t.notes.push_back(modeNote(keys));
    t.notes.push_back(oursNote(ate ? "" : "a 12-thread Xeon W-2133", frontendsOf(keys)));
    if (seed_stats && ate) t.notes.push_back(kSeedNote);
    if (any_estimate) {
      t.notes.push_back(
          "*: the shipped reference trajectory is a VIO estimate, not ground truth; our ATE is "
          "relative to it.");
    }
    addCommonNotes(&t, paper, vio ? isVioDataset : isVoDataset);
    return t;
  }

  // The seed claim over the sequences with √-f64 and √-f32 runs (VIO, then VO).
  std::optional<SeedClaim> seedClaim() const {
    SeedClaim claim;
    claim.title =
        "Seed claim: is |ATE(√-f32) − ATE(√-f64)| within the seed-to-seed spread of √-f64?";
    const std::vector<std::string> pair = {kHeadline[0], kHeadline[1]};
    using Family = std::pair<bool (*)(const std::string&), const char*>;
    for (const auto& [family, id] :
         std::initializer_list<Family>{{isVioDataset, "table1"}, {isVoDataset, "table2"}}) {
      for (const std::string& dataset : rowsFor(family, paperTable(id), pair)) {
        bool estimate = false;
        claim.rows.push_back(claimRow(dataset, rowLabel(paperTable(id), dataset, &estimate), pair));
      }
    }
    if (claim.rows.empty()) return std::nullopt;
    claim.notes = {
        "Per sequence over the seeds: mean ± sample std of the ATE [m] of √-f64 (ns-qr-sqrt-f64) "
        "and √-f32 (ns-qr-sqrt-f32) over their seeds that finished ok; |Δ| = |mean √-f32 − mean "
        "√-f64|, also relative to mean √-f64 (the paper's \"within 1 %\"); paired = mean over "
        "the seeds where both finished ok of |ATE √-f32 − ATE √-f64| (one seed: the same "
        "simulated measurements).",
        "within: yes when |Δ| ≤ std √-f64 (the f32 difference is no larger than what another "
        "seed does to f64); no when larger or when √-f32 failed on a seed; – without two ok "
        "√-f64 seeds. Seeds: `ok/finished` per variant."};
    return claim;
  }

  // The preconditioned-storage tables (issue #31 §3), made when a run has a preconditioned
  // storage: per sequence, each such variant beside the references that ran — the ATE with seed
  // statistics, or (failures) the median frame where the failed seeds stopped.
  std::optional<Table> preconditioned(bool failures) const {
    std::vector<std::string> variants, extra;
    for (const std::string& v : kPreconditionedReferences) {
      if (hasVariant(v)) variants.push_back(v);
    }
    for (const auto& [key, sel] : by_cell_) {
      if (isPreconditioned(key.column) && !std::count(extra.begin(), extra.end(), key.column)) {
        extra.push_back(key.column);
      }
    }
    if (extra.empty()) return std::nullopt;
    const auto rank = [](const std::string& v) {
      const auto it = std::find(kPreconditionedOrder.begin(), kPreconditionedOrder.end(), v);
      return std::pair{it - kPreconditionedOrder.begin(), v};
    };
    std::sort(extra.begin(), extra.end(),
              [&](const std::string& a, const std::string& b) { return rank(a) < rank(b); });
    variants.insert(variants.end(), extra.begin(), extra.end());
    Table t;
    t.id = failures ? "preconditioned_failures" : "preconditioned";
    t.title = failures ? "Preconditioned Hessian storage: median frame where the failed runs stopped"
                       : "Preconditioned Hessian storage: absolute trajectory error [m]";
    t.row_header = "sequence";
    t.quantities = {failures ? "failure_frame" : "ate"};
    t.has_paper = false;
    for (const std::string& v : variants) t.columns.push_back({v, v, v, -1, ""});
    const RunValue ate_m = [](const RunRecord& r) { return r.ate_rmse; };
    bool any_estimate = false;
    std::vector<std::string> keys;
    using Family = std::pair<bool (*)(const std::string&), const char*>;
    for (const auto& [family, id] :
         std::initializer_list<Family>{{isVioDataset, "table1"}, {isVoDataset, "table2"}}) {
      for (const std::string& dataset : rowsFor(family, paperTable(id), extra)) {
        TableRow row;
        row.key = dataset;
        row.label = rowLabel(paperTable(id), dataset, &any_estimate);
        row.frames = framesLabel(dataset, variants);
        row.ours_decimals = failures ? 0 : 4;
        for (const std::string& v : variants) {
          row.ours.push_back(failures ? failureFrameCell(select(dataset, v))
                                      : seedCell(select(dataset, v), {ate_m}));
          row.paper.emplace_back();
        }
        if (!failures) markBest(row.ours, 1, row.ours_decimals, false);
        keys.push_back(dataset);
        t.rows.push_back(std::move(row));
      }
    }
    t.notes.push_back(
        "Storages (docs/preconditioned_storage.md): sq = Hessian prior, sqrt = square-root prior; "
        "sqp = Hessian prior with 3×3 block-Jacobi preconditioning (one block per physical "
        "quantity), sqj = the same with point-Jacobi scaling, sqrtp = square-root prior made by "
        "the block-preconditioned LDLT; the preconditioning also scales the LM step's LDLT.");
    t.notes.push_back(failures
                          ? "Median over the seeds that failed of the frame where the run stopped "
                            "(index failure_frame); –: no seed failed, or no run."
                          : "ATE: results /summary ate_rmse, mean ± sample standard deviation "
                            "over the seeds whose run finished ok; `x k/n`: k of the n finished "
                            "seeds failed (left out of the mean).");
    t.notes.push_back(modeNote(keys) +
                      " Whole sequences only (runs over the first N frames are left out).");
    t.notes.push_back(failures ? "No paper values: the paper has no preconditioned storage."
                               : "Bold: best of the row; x: failed; –: no run. No paper values: "
                                 "the paper has no preconditioned storage.");
    return t;
  }

  // One ablation column's averages over the sequences (Tables 4 and 6): per sequence the mean
  // over its runs, then the mean over sequences; real-time = Σ duration / Σ (t_opt + t_marg).
  struct AblationAverages {
    TableCell::State state = TableCell::State::kValue;
    int n_runs = 0;
    double ate_m = 0, realtime = 0, t_total_s = 0, t_opt_s = 0, t_marg_s = 0;
  };
  AblationAverages ablationAverages(const std::vector<std::string>& sequences,
                                    const std::string& variant) const {
    AblationAverages out;
    std::vector<double> ate, total, opt, marg;
    double duration = 0, wall = 0;
    for (const std::string& d : sequences) {
      const Selection& sel = select(d, variant);
      out.n_runs += static_cast<int>(sel.runs.size());
      if (sel.state() == TableCell::State::kFailed) out.state = TableCell::State::kFailed;
      if (sel.state() != TableCell::State::kValue) continue;
      std::vector<double> a, w, o, m;
      for (const RunRecord* r : sel.runs) {
        a.push_back(r->ate_rmse);
        w.push_back(r->t_opt_s + r->t_marg_s);
        o.push_back(r->t_opt_s);
        m.push_back(r->t_marg_s);
        duration += r->duration_s;
        wall += r->t_opt_s + r->t_marg_s;
      }
      ate.push_back(mean(a));
      total.push_back(mean(w));
      opt.push_back(mean(o));
      marg.push_back(mean(m));
    }
    out.ate_m = mean(ate);
    out.realtime = duration / wall;
    out.t_total_s = mean(total);
    out.t_opt_s = mean(opt);
    out.t_marg_s = mean(marg);
    return out;
  }

  // The sequences of a family that have all eight ablation variants.
  std::vector<std::string> ablationSequences(bool (*family)(const std::string&)) const {
    std::vector<std::string> sequences;
    for (const std::string& d : datasets_) {
      if (!family(d)) continue;
      if (std::all_of(kAblation.begin(), kAblation.end(), [&](const std::string& v) {
            return select(d, v).state() != TableCell::State::kMissing;
          })) {
        sequences.push_back(d);
      }
    }
    return sequences;
  }

  // Tables 4 and 6.
  std::optional<Table> ablation(int number, bool (*family)(const std::string&),
                                const std::string& family_name, std::string* why) const {
    const std::string id = fmt::format("table{}", number);
    const PaperTable* paper = paperTable(id);
    const std::vector<std::string> sequences = ablationSequences(family);
    if (sequences.empty()) {
      *why = fmt::format("Table {}: no {} sequence has all eight ablation variants ({})", number,
                         family_name, fmt::join(kAblation, ", "));
      return std::nullopt;
    }
    Table t;
    t.id = id;
    t.title = fmt::format(
        "Table {}: ablation of optimization / marginalization and precision, "
        "{}, square-root prior storage (averages)",
        number, number == 4 ? "VIO on EuRoC" : "VO on KITTI");
    t.row_header = "metric";
    t.quantities = {"value"};
    t.columns = ablationColumns();
    std::vector<AblationAverages> averages;
    for (const TableColumn& column : t.columns) {
      averages.push_back(ablationAverages(sequences, column.variant));
    }
    struct Metric {
      const char* key;
      const char* label;
      int ours_decimals, paper_decimals;
      bool higher;
      const char* suffix;
      double AblationAverages::*value;
    };
    const Metric metrics[] = {
        {"ate_m", "ATE [m]", 4, 3, false, "", &AblationAverages::ate_m},
        {"realtime", "real-time", 1, 1, true, "x", &AblationAverages::realtime},
        {"t_total_s", "t total [s]", 2, 1, false, "", &AblationAverages::t_total_s},
        {"t_opt_s", "t opt [s]", 2, 1, false, "", &AblationAverages::t_opt_s},
        {"t_marg_s", "t marg [s]", 2, 1, false, "", &AblationAverages::t_marg_s}};
    for (const Metric& metric : metrics) {
      TableRow row;
      row.key = metric.key;
      row.label = metric.label;
      row.ours_decimals = metric.ours_decimals;
      row.paper_decimals = metric.paper_decimals;
      row.higher_is_better = metric.higher;
      row.suffix = metric.suffix;
      for (std::size_t c = 0; c < t.columns.size(); ++c) {
        TableCell cell;
        cell.state = averages[c].state;
        cell.n_runs = averages[c].n_runs;
        if (cell.state == TableCell::State::kValue) cell.numbers = {averages[c].*metric.value};
        row.ours.push_back(cell);
        row.paper.push_back(paperCell(paper, metric.key, t.columns[c].variant, t.quantities));
      }
      markBest(row.ours, 1, row.ours_decimals, row.higher_is_better);
      markBest(row.paper, 1, row.paper_decimals, row.higher_is_better);
      t.rows.push_back(std::move(row));
    }
    addAblationNotes(sequences, paper, &t);
    return t;
  }

  void addAblationNotes(const std::vector<std::string>& sequences, const PaperTable* paper,
                        Table* t) const {
    std::vector<std::string> labels;
    for (const std::string& d : sequences) {
      labels.push_back(fmt::format("{} ({} frames)", d, framesLabel(d, kAblation)));
    }
    t->notes.push_back(fmt::format(
        "Columns: optimization / marginalization - precision; NS = nullspace projection "
        "(NS+LDLT, NS+QR), SC = Schur complement (SC+LDLT, SC+SC); all store the prior in square "
        "root form. Ours: averages over {} sequence(s) that have all eight variants: {}.",
        sequences.size(), fmt::join(labels, ", ")));
    t->notes.push_back(
        "t total = t opt + t marg (our front-end is simulated and not timed); real-time = "
        "Σ duration / Σ t total; x: the variant failed on at least one of these sequences.");
    t->notes.push_back(modeNote(sequences));
    addCommonNotes(t, paper, nullptr);
  }

  // Hsiung et al. Table I analog; the builder's columns are marginalization strategies.
  std::optional<Table> strategyAccuracy(const std::string& id, const std::string& variant) const {
    const PaperTable* paper = paperTable("sparsify_table1");
    Table t;
    t.id = id;
    t.title = fmt::format(
        "Table I (Hsiung et al.): absolute trajectory error [m] by marginalization strategy, {}",
        variant);
    t.row_header = "sequence";
    t.quantities = {"ate"};
    for (const std::string& s : kStrategies) t.columns.push_back({s, s, s, -1, ""});
    t.columns.push_back({"nfr", "KLD nfr [nats]", "KLD nfr [nats]", 3, "kld"});
    t.columns.push_back({"nfr", "nnz nfr / dense", "nnz nfr / dense", 3, "nnz_ratio"});
    const RunValue ate_m = [](const RunRecord& r) { return r.ate_rmse; };
    const RunValue kld = [this](const RunRecord& r) { return stats(r).kld_mean; };
    const RunValue nnz_ratio = [this](const RunRecord& r) { return stats(r).nnz_ratio; };
    int events = 0, recovered = 0;
    bool any_estimate = false;
    const std::vector<std::string> datasets = rowsFor(isEurocDataset, paper, kStrategies);
    for (const std::string& dataset : datasets) {
      TableRow row;
      row.key = dataset;
      row.label = rowLabel(paper, dataset, &any_estimate);
      row.frames = framesLabel(dataset, kStrategies);
      row.ours_decimals = 4;
      row.paper_decimals = 3;
      for (const std::string& s : kStrategies) {
        row.ours.push_back(meanCell(select(dataset, s), {ate_m}));
        row.paper.push_back(paperCell(paper, dataset, s, t.quantities));
      }
      const Selection& nfr = select(dataset, "nfr");
      for (const RunValue& value : {kld, nnz_ratio}) {
        row.ours.push_back(meanCell(nfr, {value}));
        row.paper.emplace_back();
      }
      if (nfr.state() == TableCell::State::kValue) {
        for (const RunRecord* r : nfr.runs) {
          events += stats(*r).events;
          recovered += stats(*r).recovered;
        }
      }
      markBest(row.ours, 1, row.ours_decimals, false, kStrategies.size());
      markBest(row.paper, 1, row.paper_decimals, false);
      t.rows.push_back(std::move(row));
    }
    if (t.rows.empty()) return std::nullopt;
    t.notes.push_back(fmt::format(
        "ATE: RMSE of the positions after SE(3) alignment (results /summary ate_rmse) of the {} "
        "runs, by their results attribute marg_strategy.",
        variant));
    t.notes.push_back(fmt::format(
        "KLD nfr: mean D_KL(Λ_t ‖ Λ_s) [nats] (eq. 10, /sparsify kld) over the keyframe "
        "marginalizations of the nfr runs whose recovered factors replaced the dense prior; "
        "nnz nfr / dense: mean of nnz_sparse / nnz_dense over all of them (1 where nfr kept the "
        "dense prior); here {} of {} events recovered.",
        recovered, events));
    t.notes.push_back(
        "Paper: Proposed beside nfr, OKVIS (ours) — OKVIS's marginalization in the authors' "
        "pipeline — beside discard; the paper has no dense column (its OKVIS, VINS-MONO* and "
        "ROVIO are in paper_values.toml).");
    t.notes.push_back(modeNote(datasets));
    t.notes.push_back(oursNote("", frontendsOf(datasets)));
    addCommonNotes(&t, paper, isEurocDataset);
    return t;
  }

  // Hsiung et al. Table II analog: one row per sequence × strategy, the statistics as columns.
  std::optional<Table> strategyTiming(const std::string& id, const std::string& variant) const {
    const PaperTable* paper = paperTable("sparsify_table2");
    Table t;
    t.id = id;
    t.title = fmt::format(
        "Table II (Hsiung et al.): run time [s] per optimization and per keyframe "
        "marginalization by marginalization strategy, {}",
        variant);
    t.row_header = "sequence strategy";
    t.quantities = {"time_s"};
    const std::vector<std::pair<const char*, RunValue>> statistics = {
        {"opt mean", [this](const RunRecord& r) { return stats(r).opt.mean; }},
        {"opt RMSE", [this](const RunRecord& r) { return stats(r).opt.rmse; }},
        {"opt std", [this](const RunRecord& r) { return stats(r).opt.std; }},
        {"marg mean", [this](const RunRecord& r) { return stats(r).marg.mean; }},
        {"marg RMSE", [this](const RunRecord& r) { return stats(r).marg.rmse; }},
        {"marg std", [this](const RunRecord& r) { return stats(r).marg.std; }}};
    for (const auto& [label, value] : statistics) {
      // The paper's column ids: "opt mean" → "opt_mean".
      std::string key = label;
      std::replace(key.begin(), key.end(), ' ', '_');
      std::transform(key.begin(), key.end(), key.begin(), ::tolower);
      t.columns.push_back({key, label, label, -1, ""});
    }
    bool any_estimate = false;
    const std::vector<std::string> datasets = rowsFor(isEurocDataset, paper, kStrategies);
    for (const std::string& dataset : datasets) {
      for (const std::string& s : kStrategies) {
        const Selection& sel = select(dataset, s);
        if (sel.runs.empty()) continue;
        TableRow row;
        row.key = dataset + ":" + s;
        row.label = rowLabel(paper, dataset, &any_estimate) + " " + s;
        row.frames = framesLabel(dataset, {s});
        row.ours_decimals = 4;
        row.paper_decimals = 3;
        for (std::size_t c = 0; c < statistics.size(); ++c) {
          row.ours.push_back(meanCell(sel, {statistics[c].second}));
          row.paper.push_back(s == "nfr"
                                  ? paperCell(paper, dataset, t.columns[c].variant, t.quantities)
                                  : TableCell{});
        }
        t.rows.push_back(std::move(row));
      }
    }
    if (t.rows.empty()) return std::nullopt;
    t.notes.push_back(
        "opt: wall time of the optimization of every frame (/frames t_opt_s). marg: /frames "
        "t_marg_s of the frames that marginalized a keyframe — for dense and nfr the frames with "
        "a /sparsify row, for discard (no /sparsify rows) every keyframe from the (max_kfs + 1)-th "
        "on (config [window] max_kfs), since each pushes one keyframe out of the full window; it "
        "is the frame's whole marginalization event (with the oldest state's speed-bias or "
        "non-keyframe state, ended landmark tracks and, for nfr, recovery and insertion). Mean, "
        "RMSE = √mean(t²) and population std per run, averaged over seeds.");
    t.notes.push_back(
        "Paper: the proposed method only (beside our nfr rows), marginalization including "
        "sparsification.");
    t.notes.push_back(modeNote(datasets));
    t.notes.push_back(oursNote("an Intel i7-6700", frontendsOf(datasets)));
    addCommonNotes(&t, paper, nullptr, /*ranked=*/false);
    return t;
  }

 private:
  const StrategyStats& stats(const RunRecord& run) const {
    auto it = stats_.find(&run);
    if (it == stats_.end()) it = stats_.emplace(&run, readStrategyStats(run.results_path)).first;
    return it->second;
  }

  const PaperTable* paperTable(const std::string& id) const {
    const auto it = paper_.tables.find(id);
    return it == paper_.tables.end() ? nullptr : &it->second;
  }

  // ranked: the table marks the best of each row in bold.
  void addCommonNotes(Table* t, const PaperTable* paper, bool (*family)(const std::string&),
                      bool ranked = true) const {
    if (paper != nullptr) {
      t->notes.push_back(fmt::format("Paper: {} of {} ({}).",
                                     paper->source.substr(0, paper->source.find(':')),
                                     paper->paper.empty() ? paper_.source : paper->paper,
                                     fs::path(paper_.file).filename().string()));
      if (family != nullptr) {
        std::vector<std::string> absent;
        for (const auto& row : paper->rows) {
          const bool shown = std::any_of(t->rows.begin(), t->rows.end(),
                                         [&](const TableRow& r) { return r.key == row.key; });
          if (!shown) absent.push_back(row.label);
        }
        if (!absent.empty()) {
          t->notes.push_back(
              fmt::format("Paper rows without runs of ours here: {}.", fmt::join(absent, ", ")));
        }
      }
    }
    t->notes.push_back(ranked ? "Bold: best of the row among ours and among the paper's values (as "
                                "printed); x: failed; –: no run."
                              : "x: failed; –: no run.");
  }

  SeedClaimRow claimRow(const std::string& dataset, const std::string& label,
                        const std::vector<std::string>& pair) const {
    constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
    SeedClaimRow row;
    row.key = dataset;
    row.label = label;
    std::map<std::string, double> ate_64, ate_32;  // seed → ATE of the ok runs
    using Column = std::tuple<std::string, std::map<std::string, double>*, int*, int*>;
    for (const auto& [variant, ate, seeds, failed] :
         std::initializer_list<Column>{{pair[0], &ate_64, &row.seeds_64, &row.failed_64},
                                       {pair[1], &ate_32, &row.seeds_32, &row.failed_32}}) {
      for (const RunRecord* r : select(dataset, variant).runs) {
        if (r->state == RunRecord::State::kOk) (*ate)[r->row.get("seed")] = r->ate_rmse;
        *failed += r->state == RunRecord::State::kFailed;
        *seeds += r->state == RunRecord::State::kOk || r->state == RunRecord::State::kFailed;
      }
    }
    auto values = [](const std::map<std::string, double>& m) {
      std::vector<double> v;
      for (const auto& [seed, x] : m) v.push_back(x);
      return v;
    };
    row.mean_64 = ate_64.empty() ? kNaN : mean(values(ate_64));
    row.std_64 = sampleStd(values(ate_64));
    row.mean_32 = ate_32.empty() ? kNaN : mean(values(ate_32));
    row.std_32 = sampleStd(values(ate_32));
    row.delta = std::abs(row.mean_32 - row.mean_64);
    row.relative = row.delta / row.mean_64;
    std::vector<double> paired;
    for (const auto& [seed, x] : ate_32) {
      if (ate_64.count(seed)) paired.push_back(std::abs(x - ate_64.at(seed)));
    }
    row.paired = paired.empty() ? kNaN : mean(paired);
    row.verdict = !std::isfinite(row.std_64) || ate_32.empty()  ? "–"
                  : row.failed_32 > 0 || row.delta > row.std_64 ? "no"
                                                                : "yes";
    return row;
  }

  const PaperValues& paper_;
  std::map<CellKey, Selection> by_cell_;
  std::set<std::string> datasets_;
  std::map<std::string, std::set<std::string>> frontends_;  // dataset → where its tracks came from
  std::map<std::string, std::set<std::string>> modes_;       // dataset → modes
  mutable std::map<const RunRecord*, StrategyStats> stats_;  // read on first use
};

}  // namespace

bool parseSeedStats(const std::string& text, SeedStats* mode) {
  const std::map<std::string, SeedStats> names = {
      {"auto", SeedStats::kAuto}, {"on", SeedStats::kOn}, {"off", SeedStats::kOff}};
  const auto it = names.find(text);
  if (it == names.end()) return false;
  *mode = it->second;
  return true;
}

std::vector<TableSet> buildTables(const ResultSet& results, const PaperValues& paper,
                                  SeedStats seeds) {
  std::set<std::string> overrides;
  for (const RunRecord& r : results.runs) overrides.insert(r.row.get("override"));
  std::vector<TableSet> sets;
  for (const std::string& o : overrides) {
    const Builder builder(results, paper, [&o](const RunRecord& r) -> std::optional<std::string> {
      if (r.row.get("override") != o) return std::nullopt;
      return r.row.get("variant");
    });
    TableSet set;
    set.override_name = o;
    auto add = [&](std::optional<Table> t, const std::string& why) {
      if (t) {
        set.tables.push_back(std::move(*t));
      } else if (!why.empty()) {
        set.skipped.push_back(why);
      }
    };
    const auto seed_stats = [&](bool vio) {
      return seeds == SeedStats::kOn || (seeds == SeedStats::kAuto && builder.severalSeeds(vio));
    };
    add(builder.perSequence(1, true, seed_stats(true)), "Table 1: no EuRoC / TUM-VI runs");
    add(builder.perSequence(2, false, seed_stats(false)), "Table 2: no KITTI runs");
    if (seed_stats(true) || seed_stats(false)) set.claim = builder.seedClaim();
    add(builder.perSequence(3, true), "Table 3: no EuRoC / TUM-VI runs");
    std::string why;
    add(builder.ablation(4, isEurocDataset, "EuRoC", &why), why);
    add(builder.perSequence(5, false), "Table 5: no KITTI runs");
    why.clear();
    add(builder.ablation(6, isVoDataset, "KITTI", &why), why);
    // Whole sequences only: a sweep with a short group (first N frames) would otherwise put its
    // runs beside whole runs in one row.
    const Builder whole(results, paper, [&o](const RunRecord& r) -> std::optional<std::string> {
      const double frames = r.row.number("frames");
      if (r.row.get("override") != o || (std::isfinite(frames) && frames > 0)) return std::nullopt;
      return r.row.get("variant");
    });
    add(whole.preconditioned(false), "");
    add(whole.preconditioned(true), "");
    sets.push_back(std::move(set));
  }

  // The strategy tables compare runs across overrides (a strategy sweep has one per strategy), so
  // they join the set without override; one pair per variant with dense or nfr runs.
  std::set<std::string> strategy_variants;
  for (const RunRecord& r : results.runs) {
    if (r.marg_strategy == "dense" || r.marg_strategy == "nfr") {
      strategy_variants.insert(r.row.get("variant"));
    }
  }
  if (strategy_variants.empty()) return sets;
  if (sets.empty() || !sets.front().override_name.empty()) sets.insert(sets.begin(), TableSet{});
  TableSet& set = sets.front();
  for (const std::string& variant : strategy_variants) {
    const Builder builder(results, paper,
                          [&variant](const RunRecord& r) -> std::optional<std::string> {
                            if (r.row.get("variant") != variant || r.marg_strategy.empty()) {
                              return std::nullopt;
                            }
                            return r.marg_strategy;
                          });
    const std::string suffix = strategy_variants.size() > 1 ? "_" + variant : "";
    for (std::optional<Table> t : {builder.strategyAccuracy("sparsify_table1" + suffix, variant),
                                   builder.strategyTiming("sparsify_table2" + suffix, variant)}) {
      if (t) set.tables.push_back(std::move(*t));
    }
  }
  return sets;
}

}  // namespace marglab::experiment
