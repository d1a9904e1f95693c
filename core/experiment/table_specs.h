#pragma once
// Tables as data: what one published table is — which runs form which column, which quantity a
// cell holds and how it is reduced over the seeds, which rows, which paper values, which notes —
// as one TableSpec, read by the one generic builder (table_builder.cpp, buildTables). The
// project's tables are the entries of publishedTables() (table_specs.cpp): Tables 1–6 of Demmel et
// al., Hsiung et al.'s Tables I and II, the preconditioned-storage study. A new study's table is
// one more entry there (or a TableSpec handed to buildTables by a test); the builder needs no
// change for a new combination of these choices.

#include <limits>
#include <map>
#include <string>
#include <vector>

#include "core/experiment/tables.h"

namespace marglab::experiment {

// Sample standard deviation (n − 1; NaN for fewer than two) of values (their mean:
// core/common/statistics.h).
double sampleStdOf(const std::vector<double>& v);

// The moments of one per-frame series of a run (Hsiung et al.'s Table II statistics).
struct Moments {
  double mean = std::numeric_limits<double>::quiet_NaN();
  double rmse = std::numeric_limits<double>::quiet_NaN();
  double std = std::numeric_limits<double>::quiet_NaN();  // population, as RMSE² = mean² + std²
};

// What the tables read from a results file beyond /summary (NaN where the file has no such rows).
struct RunFileStats {
  double kld_mean = std::numeric_limits<double>::quiet_NaN();   // over recovered /sparsify rows
  double nnz_ratio = std::numeric_limits<double>::quiet_NaN();  // mean over all /sparsify rows
  int events = 0, recovered = 0;
  Moments opt;   // /frames t_opt_s, every frame
  Moments marg;  // /frames t_marg_s of the frames that marginalized a keyframe
  // The most negative σ_min/σ_max of the gauge-free prior over the run (/marg): 0 for an exact
  // prior, about ±ε of the precision from rounding, below for an indefinite prior.
  double worst_sigma_ratio = std::numeric_limits<double>::quiet_NaN();
};
// Reads them (table_run_stats.cpp); throws InputError.
RunFileStats readRunFileStats(const std::string& path);

// The results files' statistics of a table set's runs, each file read on first use; NaN for a run
// whose file is not in its folder.
class RunFileCache {
 public:
  const RunFileStats& of(const RunRecord& run) const;

 private:
  mutable std::map<const RunRecord*, RunFileStats> stats_;
};

// One run as a cell reads it: its index / summary values, and its results file's statistics.
struct RunView {
  const RunRecord& record;
  const RunFileCache& files;
  const RunFileStats& file() const { return files.of(record); }
};

// A number of one run (ATE, a time, a statistic of its /frames or /sparsify).
using RunValue = double (*)(const RunView&);

// Which datasets a group of rows takes.
enum class Family { kVio, kVo, kEuroc };  // EuRoC + TUM-VI; KITTI; EuRoC
bool inFamily(Family family, const std::string& dataset);

// A group of rows: the datasets of a family, in the order of a paper table's rows (which also
// gives their labels), then the others by name.
struct RowGroup {
  Family family = Family::kVio;
  std::string paper_rows;  // paper table id ("table1"); "" for dataset names, by name
};

// How a cell of ours reduces the runs (seeds) of its dataset × column.
enum class CellStat {
  kMean,            // mean over the runs; `x` when any failed, `–` when any is unfinished
  kSeeds,           // mean ± sample std over the ok seeds, `x k/n` for the failed ones
  kSeedsOnRequest,  // kSeeds when --seeds on, or auto and a cell of the rows' families holds
                    // several seeds (then the seed claim table too); kMean otherwise
  kFailureFrame,    // median frame where the failed runs stopped (`–` when none failed)
  kMedian,          // median over the finished runs with a finite value (`–` without one)
};

struct ColumnSpec {
  std::string key;                  // variant, or marginalization strategy
  std::string label_md, label_tex;  // "" → the key
  bool defines_rows = true;         // a dataset gets a row when one of these columns has runs on it
  bool optional = false;            // shown only when its key has runs in the table set
  bool ranked = true;               // competes for the row's bold
  bool paper = true;                // has the paper's value beside it (when the table has any)
  int decimals = -1;                // ≥ 0: overrides the row's (a column of another unit)
  std::string quantity;             // CSV quantity when `value` replaces the table's quantities
  RunValue value = nullptr;         // the cell's one number, instead of the table's quantities
  // A group instead of one column: every key of the table set with matching(key), in the order of
  // `order` and then by name; label = key.
  bool (*matching)(const std::string& key) = nullptr;
  std::vector<std::string> order;
};

// A quantity of a cell (a cell holds one number per quantity, e.g. opt / marg): its name in the
// paper table and the CSV, and its value per run (nullptr where the columns give it).
struct QuantitySpec {
  std::string name;
  RunValue value = nullptr;
};

// A row of an averages table (Tables 4, 6): per sequence the mean over its runs of `value`, then
// the mean over the sequences; with `per`, Σ value / Σ per over all those runs instead.
struct MetricSpec {
  std::string key, label;  // key: the paper table's `metric`
  int ours_decimals = 3, paper_decimals = 3;
  bool higher_is_better = false;
  std::string suffix;
  RunValue value = nullptr;
  RunValue per = nullptr;
};

enum class Layout {
  kPerSequence,        // a row per dataset, a column per variant (or strategy)
  kAverages,           // a row per metric, a column per variant, averaged over the sequences
                       // of the rows' families that have a finished run of every column
  kPerSequenceAndKey,  // a row per dataset × row key (strategy), a column per statistic
};

// Where the keys of the columns come from, and which runs a table set holds.
enum class Keys {
  kVariant,       // the run's variant; one table set per override
  kVariantWhole,  // the same, runs over the whole sequence only (a short group is left out)
  kVariantShort,  // the same, runs over the first N frames only (a sweep's short group)
  kMargStrategy,  // the results attribute marg_strategy, across overrides, one table per variant
                  // that has dense or nfr runs (ids get `_<variant>` when there are several)
};

// Notes under a table, in order. Texts may hold {variant}, {n}, {sequences}, {recovered},
// {events}, {columns}.
enum class NoteKind {
  kText,           // the text
  kMode,           // the estimator modes of the runs of the table's datasets, then the text
  kOurs,           // where our tracks came from; text = the paper's machine ("" none)
  kSeeds,          // the text, when the cells have seed statistics
  kEstimate,       // the text, when a row's reference is a VIO estimate (label `*`)
  kPaperSource,    // "Paper: Table N of <citation> (<file>)." when the paper table exists
  kPaperAbsent,    // the paper's rows without a run of ours
  kSequences,      // the text with {n} and {sequences} (averages tables: "<d> (<frames> frames)")
  kSparsifyEvents  // the text with {recovered} / {events}: /sparsify events of column `column`
};
struct NoteSpec {
  NoteKind kind = NoteKind::kText;
  std::string text;
  std::string column;
};

struct TableSpec {
  std::string id, title, row_header;  // title may hold {variant}
  Layout layout = Layout::kPerSequence;
  Keys keys = Keys::kVariant;
  std::string paper;  // paper table id in paper_values.toml; "" ours only (no paper columns)
  std::vector<RowGroup> rows;
  std::vector<ColumnSpec> columns;
  std::vector<QuantitySpec> quantities;
  std::vector<MetricSpec> metrics;    // kAverages
  std::vector<std::string> row_keys;  // kPerSequenceAndKey: the keys of a dataset's rows
  std::string paper_row_key;          // kPerSequenceAndKey: the row key the paper's values sit by
  CellStat cell = CellStat::kMean;
  int ours_decimals = 4, paper_decimals = 3;
  bool scientific = false;  // numbers of ours as 1.2e-07, ours_decimals in the mantissa
  bool ranked = true;       // bold: the best of each row among ours and among the paper's
  // Cells read the runs' results files: the table is absent when no cell of ours has a value (a
  // committed folder keeps its index, not its runs).
  bool needs_files = false;
  std::vector<NoteSpec> notes;
  std::string skipped;  // why the table is absent, with {columns}; "" says nothing
};

// The seed claim (tables.h, SeedClaim) compares these two variants over these rows.
struct SeedClaimSpec {
  std::string f64, f32;
  std::vector<RowGroup> rows;
};

// The project's tables, in the order they are written.
const std::vector<TableSpec>& publishedTables();
const SeedClaimSpec& publishedSeedClaim();

// The tables of `specs` from the runs (buildTables of tables.h with the published ones).
std::vector<TableSet> buildTables(const ResultSet& results, const PaperValues& paper,
                                  SeedStats seeds, const std::vector<TableSpec>& specs,
                                  const SeedClaimSpec& claim);

}  // namespace marglab::experiment
