// The one table builder (tables.h, buildTables; table_specs.h): a TableSpec says which runs form
// which column, which quantity a cell holds, how the seeds reduce, which rows, which paper values
// and notes; this file applies any such spec to the loaded runs — the seed statistics of a cell,
// the best value of a row, the papers' values beside ours.

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <set>
#include <tuple>
#include <utility>

#include "core/common/statistics.h"
#include "core/estimator/estimator_settings.h"
#include "core/experiment/table_cells.h"
#include "core/experiment/table_specs.h"
#include "core/experiment/tables.h"

namespace marglab::experiment {

namespace {

namespace fs = std::filesystem;

// frontends: where the runs' tracks came from (results file attribute "frontend").
std::string oursNote(const std::string& paper_machine, const std::set<std::string>& frontends) {
  std::vector<std::string> sources;
  for (const std::string& f : frontends) {
    sources.push_back(f == "images"   ? "the image front-end on the real images"
                      : f == "tracks" ? "track files (--tracks)"
                                      : "simulated stereo tracks along the real trajectories");
  }
  if (sources.empty()) sources.push_back("simulated stereo tracks along the real trajectories");
  return fmt::format(
      "Ours: {}, `frames` = frames per run (`all`: the whole sequence); the "
      "paper: real images, whole sequences{}",
      fmt::join(sources, "; "),
      paper_machine.empty() ? std::string(".") : ", on " + paper_machine + ".");
}

// A spec's text with its placeholders ({variant}, {n}, ...) filled in.
std::string fill(std::string text, const std::vector<std::pair<std::string, std::string>>& values) {
  for (const auto& [name, value] : values) {
    const std::string placeholder = "{" + name + "}";
    for (std::size_t p = text.find(placeholder); p != std::string::npos;
         p = text.find(placeholder, p + value.size())) {
      text.replace(p, placeholder.size(), value);
    }
  }
  return text;
}

// The column a run belongs to in a table set (its variant, or its marginalization strategy);
// nullopt: not part of the set.
using ColumnOf = std::function<std::optional<std::string>(const RunRecord&)>;

// A cell of a table set: a dataset (row) and a column key; with the seed, one run.
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

// A column of a table as built: what it prints and the spec it came from.
struct BuiltColumn {
  TableColumn column;
  const ColumnSpec* spec;
};

// What a table's notes read beyond its rows.
struct NoteContext {
  std::vector<std::string> datasets;  // the sequences of its rows (or averaged over)
  bool seed_stats = false, any_estimate = false;
  std::string variant;  // the strategy tables' variant
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

  // Whether a cell of the rows' families holds more than one seed.
  bool severalSeeds(const std::vector<RowGroup>& rows) const {
    for (const auto& [key, sel] : by_cell_) {
      for (const RowGroup& g : rows) {
        if (inFamily(g.family, key.dataset) && sel.runs.size() > 1) return true;
      }
    }
    return false;
  }

  // The table of a spec, nullopt without rows; `why` says why (spec.skipped, filled in).
  std::optional<Table> build(const TableSpec& spec, bool seed_stats, const std::string& variant,
                             std::string* why) const {
    const std::vector<BuiltColumn> columns = columnsOf(spec);
    Table t;
    t.id = spec.id;
    t.title = fill(spec.title, {{"variant", variant}});
    t.row_header = spec.row_header;
    t.has_paper = !spec.paper.empty();
    for (const QuantitySpec& q : spec.quantities) t.quantities.push_back(q.name);
    for (const BuiltColumn& c : columns) t.columns.push_back(c.column);
    NoteContext context;
    context.seed_stats = seed_stats;
    context.variant = variant;
    switch (spec.layout) {
      case Layout::kPerSequence:
        perSequenceRows(spec, columns, &t, &context);
        break;
      case Layout::kAverages:
        averageRows(spec, columns, &t, &context);
        break;
      case Layout::kPerSequenceAndKey:
        perSequenceAndKeyRows(spec, columns, &t, &context);
        break;
    }
    if (spec.needs_files && !anyValue(t)) t.rows.clear();
    if (t.rows.empty()) {
      std::vector<std::string> keys;
      for (const BuiltColumn& c : columns) keys.push_back(c.column.variant);
      *why = fill(spec.skipped, {{"columns", fmt::format("{}", fmt::join(keys, ", "))}});
      return std::nullopt;
    }
    addNotes(spec, context, &t);
    return t;
  }

  // The seed claim over the sequences with runs of both variants (tables.h, SeedClaim).
  std::optional<SeedClaim> seedClaim(const SeedClaimSpec& spec) const {
    SeedClaim claim;
    claim.title =
        "Seed claim: is |ATE(√-f32) − ATE(√-f64)| within the seed-to-seed spread of √-f64?";
    const std::vector<std::string> pair = {spec.f64, spec.f32};
    for (const RowGroup& group : spec.rows) {
      for (const std::string& dataset : rowsFor(group, pair)) {
        bool estimate = false;
        claim.rows.push_back(
            claimRow(dataset, rowLabel(paperTable(group.paper_rows), dataset, &estimate), pair));
      }
    }
    if (claim.rows.empty()) return std::nullopt;
    claim.notes = {
        fmt::format("Per sequence over the seeds: mean ± sample std of the ATE [m] of √-f64 ({}) "
                    "and √-f32 ({}) over their seeds that finished ok; |Δ| = |mean √-f32 − mean "
                    "√-f64|, also relative to mean √-f64 (the paper's \"within 1 %\"); paired = "
                    "mean over the seeds where both finished ok of |ATE √-f32 − ATE √-f64| (one "
                    "seed: the same simulated measurements).",
                    spec.f64, spec.f32),
        "within: yes when |Δ| ≤ std √-f64 (the f32 difference is no larger than what another "
        "seed does to f64); no when larger or when √-f32 failed on a seed; – without two ok "
        "√-f64 seeds. Seeds: `ok/finished` per variant."};
    return claim;
  }

 private:
  static bool anyValue(const Table& t) {
    return std::any_of(t.rows.begin(), t.rows.end(), [](const TableRow& row) {
      return std::any_of(row.ours.begin(), row.ours.end(), [](const TableCell& cell) {
        return cell.state == TableCell::State::kValue;
      });
    });
  }

  // The spec's columns as built: optional ones only when they ran, groups expanded.
  std::vector<BuiltColumn> columnsOf(const TableSpec& spec) const {
    std::vector<BuiltColumn> columns;
    for (const ColumnSpec& c : spec.columns) {
      if (c.matching != nullptr) {
        for (const std::string& key : matchingKeys(c)) {
          columns.push_back({{key, key, key, c.decimals, c.quantity}, &c});
        }
        continue;
      }
      if (c.optional && !hasKey(c.key)) continue;
      columns.push_back({{c.key, c.label_md.empty() ? c.key : c.label_md,
                          c.label_tex.empty() ? c.key : c.label_tex, c.decimals, c.quantity},
                         &c});
    }
    return columns;
  }

  // The keys of a column group: in the group's order, then by name.
  std::vector<std::string> matchingKeys(const ColumnSpec& group) const {
    std::vector<std::string> keys;
    for (const auto& [key, sel] : by_cell_) {
      if (group.matching(key.column) && !std::count(keys.begin(), keys.end(), key.column)) {
        keys.push_back(key.column);
      }
    }
    const auto rank = [&group](const std::string& k) {
      return std::pair{std::find(group.order.begin(), group.order.end(), k) - group.order.begin(),
                       k};
    };
    std::sort(keys.begin(), keys.end(),
              [&](const std::string& a, const std::string& b) { return rank(a) < rank(b); });
    return keys;
  }

  bool hasKey(const std::string& column) const {
    return std::any_of(by_cell_.begin(), by_cell_.end(),
                       [&column](const auto& cell) { return cell.first.column == column; });
  }

  const Selection& select(const std::string& dataset, const std::string& column) const {
    static const Selection kNone;
    const auto it = by_cell_.find(CellKey{dataset, column});
    return it == by_cell_.end() ? kNone : it->second;
  }

  const PaperTable* paperTable(const std::string& id) const {
    const auto it = paper_.tables.find(id);
    return it == paper_.tables.end() ? nullptr : &it->second;
  }

  // The keys of the columns that decide which datasets get a row.
  static std::vector<std::string> rowDefining(const std::vector<BuiltColumn>& columns) {
    std::vector<std::string> keys;
    for (const BuiltColumn& c : columns) {
      if (c.spec->defines_rows) keys.push_back(c.column.variant);
    }
    return keys;
  }

  // Datasets of a row group with runs of one of these columns, in the paper's row order, then the
  // others by name.
  std::vector<std::string> rowsFor(const RowGroup& group,
                                   const std::vector<std::string>& columns) const {
    std::vector<std::string> rows;
    auto present = [&](const std::string& d) {
      return std::any_of(columns.begin(), columns.end(),
                         [&](const std::string& c) { return !select(d, c).runs.empty(); });
    };
    if (const PaperTable* table = paperTable(group.paper_rows)) {
      for (const auto& row : table->rows) {
        if (datasets_.count(row.key) && present(row.key)) rows.push_back(row.key);
      }
    }
    for (const std::string& d : datasets_) {
      if (inFamily(group.family, d) && present(d) &&
          std::find(rows.begin(), rows.end(), d) == rows.end()) {
        rows.push_back(d);
      }
    }
    return rows;
  }

  std::string framesLabel(const std::string& dataset,
                          const std::vector<std::string>& columns) const {
    double most = 0;
    for (const std::string& c : columns) {
      for (const RunRecord* r : select(dataset, c).runs) {
        double f = r->row.number("frames");
        if (!std::isfinite(f) || f <= 0) f = 0;
        // A part's frames, never "all" (issue 38 item 6).
        if (r->partial_frames > 0) f = r->partial_frames;
        if (f <= 0) return "all";
        most = std::max(most, f);
      }
    }
    return most > 0 ? fmt::format("{:.0f}", most) : "";
  }

  // Whether a run of the row covers part of its sequence: the paper's whole-sequence values stay
  // away.
  bool partialRow(const std::string& dataset) const {
    for (const auto& [key, sel] : by_cell_) {
      if (key.dataset != dataset) continue;
      for (const RunRecord* r : sel.runs) {
        if (r->partial_frames > 0) return true;
      }
    }
    return false;
  }

  // The paper's label of a dataset, `*` when a run's reference is a VIO estimate.
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

  // A cell of ours, reduced over the seeds as the spec says.
  TableCell cellOf(CellStat stat, bool seed_stats, const Selection& sel,
                   const std::vector<RunValue>& values) const {
    if (stat == CellStat::kFailureFrame) return failureFrameCell(sel);
    if (stat == CellStat::kMedian) return medianOfRuns(sel, values.front(), files_);
    return seed_stats ? seedCell(sel, values, files_) : meanCell(sel, values, files_);
  }

  // A column's values per run: its own, or the table's quantities.
  static std::vector<RunValue> valuesOf(const TableSpec& spec, const ColumnSpec& column) {
    if (column.value != nullptr) return {column.value};
    std::vector<RunValue> values;
    for (const QuantitySpec& q : spec.quantities) values.push_back(q.value);
    return values;
  }

  // Bold on a row: the best among the ranked columns of ours, among all of the paper's.
  static void rankRow(const TableSpec& spec, const std::vector<BuiltColumn>& columns,
                      TableRow* row) {
    if (!spec.ranked) return;
    std::vector<bool> ranked;
    for (const BuiltColumn& c : columns) ranked.push_back(c.spec->ranked);
    const std::size_t n = spec.quantities.size();
    markBest(row->ours, n, row->ours_decimals, row->higher_is_better, ranked);
    markBest(row->paper, n, row->paper_decimals, row->higher_is_better,
             std::vector<bool>(columns.size(), true));
  }

  // A row per dataset of the row groups, a cell per column.
  void perSequenceRows(const TableSpec& spec, const std::vector<BuiltColumn>& columns, Table* t,
                       NoteContext* context) const {
    const std::vector<std::string> defining = rowDefining(columns);
    const PaperTable* paper = paperTable(spec.paper);
    for (const RowGroup& group : spec.rows) {
      const PaperTable* labels = paperTable(group.paper_rows);
      for (const std::string& dataset : rowsFor(group, defining)) {
        TableRow row;
        row.key = dataset;
        row.label = rowLabel(labels, dataset, &context->any_estimate);
        row.frames = framesLabel(dataset, defining);
        const bool partial = partialRow(dataset);
        row.ours_decimals = spec.ours_decimals;
        row.paper_decimals = spec.paper_decimals;
        row.scientific = spec.scientific;
        for (const BuiltColumn& c : columns) {
          row.ours.push_back(cellOf(spec.cell, context->seed_stats,
                                    select(dataset, c.column.variant), valuesOf(spec, *c.spec)));
          row.paper.push_back(c.spec->paper && !partial
                                  ? paperCell(paper, dataset, c.column.variant, t->quantities)
                                  : TableCell{});
        }
        rankRow(spec, columns, &row);
        context->datasets.push_back(dataset);
        t->rows.push_back(std::move(row));
      }
    }
  }

  // A row per dataset × row key with runs, a cell per column (a statistic); the paper's values
  // beside the rows of spec.paper_row_key.
  void perSequenceAndKeyRows(const TableSpec& spec, const std::vector<BuiltColumn>& columns,
                             Table* t, NoteContext* context) const {
    const PaperTable* paper = paperTable(spec.paper);
    for (const RowGroup& group : spec.rows) {
      const PaperTable* labels = paperTable(group.paper_rows);
      for (const std::string& dataset : rowsFor(group, spec.row_keys)) {
        context->datasets.push_back(dataset);
        for (const std::string& key : spec.row_keys) {
          const Selection& sel = select(dataset, key);
          if (sel.runs.empty()) continue;
          TableRow row;
          row.key = dataset + ":" + key;
          row.label = rowLabel(labels, dataset, &context->any_estimate) + " " + key;
          row.frames = framesLabel(dataset, {key});
          row.ours_decimals = spec.ours_decimals;
          row.paper_decimals = spec.paper_decimals;
          for (const BuiltColumn& c : columns) {
            row.ours.push_back(
                cellOf(spec.cell, context->seed_stats, sel, valuesOf(spec, *c.spec)));
            row.paper.push_back(key == spec.paper_row_key && !partialRow(dataset)
                                    ? paperCell(paper, dataset, c.column.variant, t->quantities)
                                    : TableCell{});
          }
          rankRow(spec, columns, &row);
          t->rows.push_back(std::move(row));
        }
      }
    }
  }

  // The sequences of the row groups with a finished run of every column (averages tables).
  std::vector<std::string> completeSequences(const TableSpec& spec,
                                             const std::vector<BuiltColumn>& columns) const {
    std::vector<std::string> sequences;
    for (const RowGroup& group : spec.rows) {
      for (const std::string& d : datasets_) {
        if (inFamily(group.family, d) &&
            std::all_of(columns.begin(), columns.end(), [&](const BuiltColumn& c) {
              return select(d, c.column.variant).state() != TableCell::State::kMissing;
            })) {
          sequences.push_back(d);
        }
      }
    }
    return sequences;
  }

  // One column's cell per metric, averaged over the sequences (MetricSpec).
  std::vector<TableCell> averages(const std::vector<std::string>& sequences,
                                  const std::string& column,
                                  const std::vector<MetricSpec>& metrics) const {
    TableCell cell;
    cell.state = TableCell::State::kValue;
    std::vector<std::vector<double>> per_sequence(metrics.size());
    std::vector<double> sums(metrics.size(), 0), pers(metrics.size(), 0);
    for (const std::string& d : sequences) {
      const Selection& sel = select(d, column);
      cell.n_runs += static_cast<int>(sel.runs.size());
      if (sel.state() == TableCell::State::kFailed) cell.state = TableCell::State::kFailed;
      if (sel.state() != TableCell::State::kValue) continue;
      for (std::size_t m = 0; m < metrics.size(); ++m) {
        std::vector<double> v;
        for (const RunRecord* r : sel.runs) {
          v.push_back(metrics[m].value(RunView{*r, files_}));
          sums[m] += v.back();
          if (metrics[m].per != nullptr) pers[m] += metrics[m].per(RunView{*r, files_});
        }
        per_sequence[m].push_back(mean(v));
      }
    }
    std::vector<TableCell> cells(metrics.size(), cell);
    for (std::size_t m = 0; m < metrics.size(); ++m) {
      if (cell.state != TableCell::State::kValue) continue;
      cells[m].numbers = {metrics[m].per != nullptr ? sums[m] / pers[m] : mean(per_sequence[m])};
    }
    return cells;
  }

  // A row per metric, a cell per column averaged over the complete sequences.
  void averageRows(const TableSpec& spec, const std::vector<BuiltColumn>& columns, Table* t,
                   NoteContext* context) const {
    context->datasets = completeSequences(spec, columns);
    if (context->datasets.empty()) return;
    std::vector<std::vector<TableCell>> by_column;
    for (const BuiltColumn& c : columns) {
      by_column.push_back(averages(context->datasets, c.column.variant, spec.metrics));
    }
    // The paper's averages are over whole sequences.
    const bool partial = std::any_of(context->datasets.begin(), context->datasets.end(),
                                     [this](const std::string& d) { return partialRow(d); });
    const PaperTable* paper = partial ? nullptr : paperTable(spec.paper);
    for (std::size_t m = 0; m < spec.metrics.size(); ++m) {
      const MetricSpec& metric = spec.metrics[m];
      TableRow row{metric.key,
                   metric.label,
                   "",
                   metric.ours_decimals,
                   metric.paper_decimals,
                   metric.higher_is_better,
                   metric.suffix,
                   /*scientific=*/false,
                   {},
                   {}};
      for (std::size_t c = 0; c < columns.size(); ++c) {
        row.ours.push_back(by_column[c][m]);
        row.paper.push_back(paperCell(paper, metric.key, columns[c].column.variant, t->quantities));
      }
      rankRow(spec, columns, &row);
      t->rows.push_back(std::move(row));
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

  // The /sparsify events of the finished runs of one column over the table's datasets, and how
  // many of them recovered factors.
  std::pair<int, int> sparsifyEvents(const std::vector<std::string>& datasets,
                                     const std::string& column) const {
    int events = 0, recovered = 0;
    for (const std::string& d : datasets) {
      const Selection& sel = select(d, column);
      if (sel.state() != TableCell::State::kValue) continue;
      for (const RunRecord* r : sel.runs) {
        events += files_.of(*r).events;
        recovered += files_.of(*r).recovered;
      }
    }
    return {events, recovered};
  }

  // "Paper: Table N of <citation> (<file>)."; the paper's rows without a run of ours.
  std::optional<std::string> paperNote(NoteKind kind, const PaperTable* paper,
                                       const Table& t) const {
    if (paper == nullptr) return std::nullopt;
    if (kind == NoteKind::kPaperSource) {
      return fmt::format("Paper: {} of {} ({}).", paper->source.substr(0, paper->source.find(':')),
                         paper->paper.empty() ? paper_.source : paper->paper,
                         fs::path(paper_.file).filename().string());
    }
    std::vector<std::string> absent;
    for (const auto& row : paper->rows) {
      const bool shown = std::any_of(t.rows.begin(), t.rows.end(),
                                     [&](const TableRow& r) { return r.key == row.key; });
      if (!shown) absent.push_back(row.label);
    }
    if (absent.empty()) return std::nullopt;
    return fmt::format("Paper rows without runs of ours here: {}.", fmt::join(absent, ", "));
  }

  // One note of the spec; nullopt when it does not apply to this table.
  std::optional<std::string> noteText(const NoteSpec& note, const NoteContext& context,
                                      const PaperTable* paper, const Table& t) const {
    switch (note.kind) {
      case NoteKind::kText:
        return fill(note.text, {{"variant", context.variant}});
      case NoteKind::kMode:
        return modeNote(context.datasets) + note.text;
      case NoteKind::kOurs:
        return oursNote(note.text, frontendsOf(context.datasets));
      case NoteKind::kSeeds:
        return context.seed_stats ? std::optional(note.text) : std::nullopt;
      case NoteKind::kEstimate:
        return context.any_estimate ? std::optional(note.text) : std::nullopt;
      case NoteKind::kPaperSource:
      case NoteKind::kPaperAbsent:
        return paperNote(note.kind, paper, t);
      case NoteKind::kSequences: {
        std::vector<std::string> labels;
        for (const std::string& d : context.datasets) {
          labels.push_back(fmt::format("{} ({} frames)", d, framesLabel(d, columnKeys(t))));
        }
        return fill(note.text, {{"n", std::to_string(context.datasets.size())},
                                {"sequences", fmt::format("{}", fmt::join(labels, ", "))}});
      }
      case NoteKind::kSparsifyEvents: {
        const auto [events, recovered] = sparsifyEvents(context.datasets, note.column);
        return fill(note.text,
                    {{"recovered", std::to_string(recovered)}, {"events", std::to_string(events)}});
      }
    }
    return std::nullopt;
  }

  static std::vector<std::string> columnKeys(const Table& t) {
    std::vector<std::string> keys;
    for (const TableColumn& c : t.columns) keys.push_back(c.variant);
    return keys;
  }

  void addNotes(const TableSpec& spec, const NoteContext& context, Table* t) const {
    const PaperTable* paper = paperTable(spec.paper);
    for (const NoteSpec& note : spec.notes) {
      if (std::optional<std::string> text = noteText(note, context, paper, *t)) {
        t->notes.push_back(std::move(*text));
      }
    }
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
    row.std_64 = sampleStdOf(values(ate_64));
    row.mean_32 = ate_32.empty() ? kNaN : mean(values(ate_32));
    row.std_32 = sampleStdOf(values(ate_32));
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
  std::map<std::string, std::set<std::string>> modes_;      // dataset → modes
  RunFileCache files_;
};

// The builders of one override: every run, the whole-sequence runs and those of a short group (the
// first N frames; a sweep with one would otherwise put its runs beside whole runs in one row).
TableSet overrideSet(const ResultSet& results, const PaperValues& paper, SeedStats seeds,
                     const std::vector<TableSpec>& specs, const SeedClaimSpec& claim_spec,
                     const std::string& o) {
  const Builder all(results, paper, [&o](const RunRecord& r) -> std::optional<std::string> {
    if (r.row.get("override") != o) return std::nullopt;
    return r.row.get("variant");
  });
  const auto length = [&o](bool short_group) {
    return [&o, short_group](const RunRecord& r) -> std::optional<std::string> {
      const double frames = r.row.number("frames");
      if (r.row.get("override") != o || (std::isfinite(frames) && frames > 0) != short_group) {
        return std::nullopt;
      }
      return r.row.get("variant");
    };
  };
  const Builder whole(results, paper, length(false)), short_group(results, paper, length(true));
  TableSet set;
  set.override_name = o;
  bool claim = false;
  for (const TableSpec& spec : specs) {
    if (spec.keys == Keys::kMargStrategy) continue;
    const Builder& builder = spec.keys == Keys::kVariantWhole   ? whole
                             : spec.keys == Keys::kVariantShort ? short_group
                                                                : all;
    const bool on_request =
        spec.cell == CellStat::kSeedsOnRequest &&
        (seeds == SeedStats::kOn || (seeds == SeedStats::kAuto && builder.severalSeeds(spec.rows)));
    claim = claim || on_request;
    std::string why;
    if (std::optional<Table> t =
            builder.build(spec, on_request || spec.cell == CellStat::kSeeds, "", &why)) {
      set.tables.push_back(std::move(*t));
    } else if (!why.empty()) {
      set.skipped.push_back(why);
    }
  }
  if (claim) set.claim = all.seedClaim(claim_spec);
  return set;
}

// The strategy tables compare runs across overrides (a strategy sweep has one per strategy), so
// they join the set without override; one table per spec and variant with dense or nfr runs.
void addStrategyTables(const ResultSet& results, const PaperValues& paper,
                       const std::vector<TableSpec>& specs, std::vector<TableSet>* sets) {
  std::set<std::string> variants;
  for (const RunRecord& r : results.runs) {
    MargStrategy strategy = MargStrategy::kDiscard;
    if (parseMargStrategy(r.marg_strategy, &strategy) && strategy != MargStrategy::kDiscard) {
      variants.insert(r.row.get("variant"));
    }
  }
  if (variants.empty()) return;
  if (sets->empty() || !sets->front().override_name.empty())
    sets->insert(sets->begin(), TableSet{});
  for (const std::string& variant : variants) {
    const Builder builder(results, paper,
                          [&variant](const RunRecord& r) -> std::optional<std::string> {
                            if (r.row.get("variant") != variant || r.marg_strategy.empty()) {
                              return std::nullopt;
                            }
                            return r.marg_strategy;
                          });
    const std::string suffix = variants.size() > 1 ? "_" + variant : "";
    for (const TableSpec& spec : specs) {
      if (spec.keys != Keys::kMargStrategy) continue;
      std::string why;
      if (std::optional<Table> t =
              builder.build(spec, spec.cell == CellStat::kSeeds, variant, &why)) {
        t->id += suffix;
        sets->front().tables.push_back(std::move(*t));
      }
    }
  }
}

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
                                  SeedStats seeds, const std::vector<TableSpec>& specs,
                                  const SeedClaimSpec& claim) {
  std::set<std::string> overrides;
  for (const RunRecord& r : results.runs) overrides.insert(r.row.get("override"));
  std::vector<TableSet> sets;
  for (const std::string& o : overrides) {
    sets.push_back(overrideSet(results, paper, seeds, specs, claim, o));
  }
  addStrategyTables(results, paper, specs, &sets);
  return sets;
}

std::vector<TableSet> buildTables(const ResultSet& results, const PaperValues& paper,
                                  SeedStats seeds) {
  return buildTables(results, paper, seeds, publishedTables(), publishedSeedClaim());
}

}  // namespace marglab::experiment
