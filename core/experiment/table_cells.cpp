// The cells of a table (table_cells.h): a cell of ours from the runs of one dataset × column,
// the paper's cell beside it, the best value of a row.

#include "core/experiment/table_cells.h"
#include "core/common/statistics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace marglab::experiment {

namespace {

double roundTo(double v, int decimals) {
  const double scale = std::pow(10.0, decimals);
  return std::round(v * scale) / scale;
}

// A cell of the median of values, n_runs their number (kMissing, "–", without one).
TableCell medianCell(std::vector<double> values) {
  TableCell cell;
  cell.n_runs = static_cast<int>(values.size());
  if (values.empty()) return cell;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  cell.state = TableCell::State::kValue;
  cell.numbers = {n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2])};
  return cell;
}

}  // namespace

TableCell::State Selection::state() const {
  if (runs.empty()) return TableCell::State::kMissing;
  bool missing = false;
  for (const RunRecord* r : runs) {
    if (r->state == RunRecord::State::kFailed) return TableCell::State::kFailed;
    if (r->state != RunRecord::State::kOk) missing = true;
  }
  return missing ? TableCell::State::kMissing : TableCell::State::kValue;
}

// Marks the best value(s) of a row per quantity, compared as printed; only the cells with
// ranked[c] compete (the others are columns of another quantity).
void markBest(std::vector<TableCell>& cells, std::size_t quantities, int decimals, bool higher,
              const std::vector<bool>& ranked) {
  for (auto& cell : cells) cell.best.assign(quantities, false);
  const auto competes = [&](std::size_t c) {
    const TableCell& cell = cells[c];
    return ranked[c] && cell.state == TableCell::State::kValue;
  };
  for (std::size_t q = 0; q < quantities; ++q) {
    double best =
        higher ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
    bool any = false;
    for (std::size_t c = 0; c < cells.size(); ++c) {
      if (!competes(c) || !std::isfinite(cells[c].numbers[q])) continue;
      const double r = roundTo(cells[c].numbers[q], decimals);
      best = higher ? std::max(best, r) : std::min(best, r);
      any = true;
    }
    if (!any) continue;
    for (std::size_t c = 0; c < cells.size(); ++c) {
      if (competes(c) && std::isfinite(cells[c].numbers[q]) &&
          roundTo(cells[c].numbers[q], decimals) == best) {
        cells[c].best[q] = true;
      }
    }
  }
}

TableCell paperCell(const PaperTable* table, const std::string& row_key, const std::string& column,
                    const std::vector<std::string>& quantities) {
  TableCell cell;
  if (table == nullptr) return cell;
  const PaperTable::Row* row = table->row(row_key);
  const auto col = std::find(table->columns.begin(), table->columns.end(), column);
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

// A cell of ours: the mean over the selection's runs (seeds) of each quantity.
TableCell meanCell(const Selection& sel, const std::vector<RunValue>& quantities,
                   const RunFileCache& files) {
  TableCell cell;
  cell.state = sel.state();
  cell.n_runs = static_cast<int>(sel.runs.size());
  if (cell.state != TableCell::State::kValue) return cell;
  for (const RunValue value : quantities) {
    std::vector<double> v;
    for (const RunRecord* r : sel.runs) v.push_back(value(RunView{*r, files}));
    cell.numbers.push_back(mean(v));
  }
  return cell;
}

// A cell of ours with seed statistics (TableCell::seed_stats): the ok seeds give the mean and
// spread, the failed ones the count; unfinished runs are left out.
TableCell seedCell(const Selection& sel, const std::vector<RunValue>& quantities,
                   const RunFileCache& files) {
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
  for (const RunValue value : quantities) {
    std::vector<double> v;
    for (const RunRecord* r : ok) v.push_back(value(RunView{*r, files}));
    cell.numbers.push_back(mean(v));
    cell.spread.push_back(sampleStdOf(v));
  }
  return cell;
}

// The median frame where the failed runs of a selection stopped.
TableCell failureFrameCell(const Selection& sel) {
  std::vector<double> frames;
  for (const RunRecord* r : sel.runs) {
    if (r->state == RunRecord::State::kFailed && r->failure_frame >= 0) {
      frames.push_back(static_cast<double>(r->failure_frame));
    }
  }
  return medianCell(std::move(frames));
}

// The median of one value over the finished runs of a selection where it is finite (a run whose
// results file is not in its folder has none).
TableCell medianOfRuns(const Selection& sel, RunValue value, const RunFileCache& files) {
  std::vector<double> values;
  for (const RunRecord* r : sel.runs) {
    if (r->state == RunRecord::State::kMissing) continue;
    const double v = value(RunView{*r, files});
    if (std::isfinite(v)) values.push_back(v);
  }
  return medianCell(std::move(values));
}

}  // namespace marglab::experiment
