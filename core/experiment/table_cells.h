#pragma once
// The cells of a table (table_builder.cpp's parts that do not depend on the spec): how the runs
// (seeds) of one dataset × column reduce to a cell of ours, the paper's cell beside it, and the
// best value of a row.

#include <string>
#include <vector>

#include "core/experiment/table_specs.h"
#include "core/experiment/tables.h"

namespace marglab::experiment {

// The runs of one dataset × column (all seeds) of a table set.
struct Selection {
  std::vector<const RunRecord*> runs;
  // kFailed when a run failed, kMissing when one is unfinished (or none), kValue otherwise.
  TableCell::State state() const;
};

// The mean over the selection's runs of each quantity; `x` when any failed.
TableCell meanCell(const Selection& sel, const std::vector<RunValue>& quantities,
                   const RunFileCache& files);
// Seed statistics (TableCell::seed_stats): the ok seeds give the mean and spread, the failed ones
// the count; unfinished runs are left out.
TableCell seedCell(const Selection& sel, const std::vector<RunValue>& quantities,
                   const RunFileCache& files);
// The median frame where the failed runs stopped (kMissing, "–", when none failed).
TableCell failureFrameCell(const Selection& sel);
// The median of one value over the finished runs where it is finite (a run whose results file is
// not in its folder has none).
TableCell medianOfRuns(const Selection& sel, RunValue value, const RunFileCache& files);

// The paper's cell of a row and column (kMissing where the table has none).
TableCell paperCell(const PaperTable* table, const std::string& row_key, const std::string& column,
                    const std::vector<std::string>& quantities);

// Marks the best value(s) of a row per quantity, compared as printed; only the cells with
// ranked[c] compete (the others are columns of another quantity).
void markBest(std::vector<TableCell>& cells, std::size_t quantities, int decimals, bool higher,
              const std::vector<bool>& ranked);

}  // namespace marglab::experiment
