#pragma once
// Regenerates Tables 1–6 of Demmel et al. (ICCV 2021) from sweep results, with the paper's
// published values (experiments/paper_values.toml) beside ours:
//
//   Table 1  ATE [m] per sequence, VIO (EuRoC, TUM-VI)         columns √-64, √-32, SC-64, SC-32
//   Table 2  ATE [m] per sequence, VO (KITTI)                   (ns-qr-sqrt, sc-sc-sq × f64/f32)
//   Table 3  runtime [s] optimization / marginalization, VIO
//   Table 5  the same for VO
//   Table 4  ablation on EuRoC: ATE, real-time factor, t total / opt / marg, averaged over the
//   Table 6  ablation on KITTI   sequences that have all eight square-root-storage variants
//
// Every value of ours is read from the runs' HDF5 results files (/summary: ate_rmse,
// t_opt_total_s, t_marg_total_s, wall_time_s, duration_s; root attribute status) — never from
// the index. Rules, also stated under each table:
//   - a cell is `x` when any of its runs failed (numerically, or the process died), `–` when it
//     has no run (not planned, or not finished);
//   - several seeds: the mean over seeds; Tables 1 and 2 with seed statistics (SeedStats, automatic
//     when a cell holds several seeds): mean ± sample std over the seeds that finished ok, and
//     `x k/n` when k of the n finished seeds failed (a cell is `x n/n` only when all failed);
//   - ablation averages are over the sequences that have all eight variants; a variant that
//     failed on one of them is `x`; real-time factor = Σ duration / Σ (t_opt + t_marg);
//     t total = t_opt + t_marg (the front-end is simulated, so it is not timed);
//   - bold: the best value of the row (lowest; highest real-time factor) among ours, and among the
//     paper's, compared as printed, so that ties are all bold as in the paper;
//   - when the same dataset × variant × seed × override was run more than once (several groups or
//     folders), the run with more requested frames is used.
// One table set per override name of the sweep ("" = runs without override).
//
// Seed claim (issue #19, with seed statistics): the paper's "√-f32 ATE within 1 % of f64"
// restated per sequence as a test a reader can check over seeds — is |mean ATE(√-f32) −
// mean ATE(√-f64)| within the seed-to-seed spread (sample std) of √-f64? (seed_claim.md/tex/csv)
//
// Marginalization strategies (issue #9; Hsiung et al., Information Sparsification in
// Visual-Inertial Odometry, IROS 2018), produced when some run's results attribute marg_strategy
// is dense or nfr, across overrides and folders, in the set without override:
//   sparsify_table1  (Table I)  ATE [m] of nfr, dense, discard per EuRoC sequence, the paper's
//                    Proposed (= nfr) and OKVIS (ours) (= discard) beside; the mean KLD [nats] of
//                    the nfr runs' recovered events (/sparsify kld) and their mean nnz_sparse /
//                    nnz_dense over all /sparsify rows (a fallback to the dense prior counts 1)
//   sparsify_table2  (Table II) per sequence × strategy: optimization time per frame (/frames
//                    t_opt_s) and marginalization time per keyframe marginalization, mean / RMSE /
//                    std [s], the paper's (Proposed) beside the nfr rows
// Runs are grouped by (dataset, marg_strategy) within one variant: one table pair per variant
// that has dense or nfr runs (ids get `_<variant>` when there are several). Deduplication and
// seeds as above.
//
// Preconditioned Hessian storage (issue #31 §3, docs/preconditioned_storage.md), produced when
// some whole-sequence run has a preconditioned storage (sqp, sqj, sqrtp), per override set:
//   preconditioned           ATE [m] per sequence (VIO, then VO) of each such variant beside the
//                            references that ran (ns-qr-sqrt-f32, sc-sc-sq-f32, sc-sc-sqrt-f32),
//                            with seed statistics
//   preconditioned_failures  the median frame where the failed seeds of each cell stopped
//   preconditioned_sigma     the most negative σ_min/σ_max of each run's gauge-free prior (/marg),
//                            median over the seeds; only when the runs' results files are there
// Ours only (Table::has_paper false: the paper has no such storage); runs over the first N frames
// are left out, so that a short group never sits beside whole runs in one row; the same three
// over a short group's runs only: preconditioned_short, preconditioned_failures_short,
// preconditioned_sigma_short.
//
// Every table above is one declarative TableSpec (table_specs.h: columns, quantity, seed
// statistics, rows, paper values, notes), listed in publishedTables() (table_specs.cpp) and made by
// the one generic builder; a new study's table is one more entry there.
//
// One unit per job: paper_values.cpp (loadPaperValues), results_loading.cpp (loadResults),
// table_specs.cpp (the tables as data), table_builder.cpp (buildTables: any spec from the runs),
// table_cells.cpp (a cell from its runs, the paper's cell, the best of a row), table_run_stats.cpp
// (what a cell reads from a results file beyond /summary), table_render.cpp (Markdown / LaTeX /
// CSV) and tables.cpp (writeTables: the verb's files).

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/experiment/sweep_index.h"

namespace marglab::experiment {

// ---- the paper's values -------------------------------------------------------------------------

struct PaperCell {
  enum class State { kValue, kFailed, kMissing } state = State::kMissing;
  double value = 0;
};

struct PaperTable {
  std::string id;                       // "table1"
  std::string source;                   // "Table 1: ..."
  std::string paper;                    // citation when not the file's `source` ("" otherwise)
  std::vector<std::string> columns;     // variants
  std::vector<std::string> quantities;  // "ate" | "opt", "marg" | "value"
  struct Row {
    std::string key;    // dataset ("kitti/10") or metric ("ate_m")
    std::string label;  // the paper's row label
    std::map<std::string, std::vector<PaperCell>> cells;  // quantity → one per column
  };
  std::vector<Row> rows;
  const Row* row(const std::string& key) const;
};

struct PaperValues {
  std::string file;
  std::string source;  // citation
  std::map<std::string, PaperTable> tables;
};

// Reads experiments/paper_values.toml; throws InputError(file, line, what).
PaperValues loadPaperValues(const std::string& path);
std::string defaultPaperValuesPath();  // <source dir>/experiments/paper_values.toml

// ---- our results --------------------------------------------------------------------------------

struct RunRecord {
  IndexRow row;              // the index row
  std::string dir;           // the sweep folder it came from
  std::string results_path;  // absolute or relative to the working directory
  // kMissing: no complete results file, and not failed.
  enum class State { kOk, kFailed, kMissing } state = State::kMissing;
  std::string mode;           // results file attribute "mode" ("vo" | "vio")
  std::string gt_source;      // results file attribute "gt_source" (may be "")
  std::string marg_strategy;  // results file attribute "marg_strategy" ("" without a file)
  std::string frontend;       // results file attribute "frontend" ("" without a file)
  double ate_rmse = 0, t_opt_s = 0, t_marg_s = 0, wall_s = 0, duration_s = 0;
  long long n_frames = 0;
  long long failure_frame = -1;
  std::string indexed_dataset;  // the index's "dataset" (row's "dataset" is the table's key)
  // A run over part of the sequence it records, the frames it covers: a user's folder that holds a
  // clip of it, or `frames` = N below the sequence's length. 0 for a whole sequence, or when the
  // sequence can no longer be read. The paper's whole-sequence values never stand beside it.
  long long partial_frames = 0;
};

struct ResultSet {
  std::vector<RunRecord> runs;
  std::vector<std::string> warnings;
};

// Reads <dir>/index.csv of each folder and every results file it lists. A run whose results file
// is not in the folder (a committed sweep folder keeps its index, not runs/) is read from its index
// row, whose summary columns the sweep copied from the file; a warning counts them per folder.
// Rows are keyed by the dataset's identity: two datasets that record the same name (two user
// folders called 06) keep apart as "kitti/06 (FOLDER)", with a warning.
ResultSet loadResults(const std::vector<std::string>& dirs);

// ---- tables -------------------------------------------------------------------------------------

struct TableCell {
  enum class State { kValue, kFailed, kMissing } state = State::kMissing;
  std::vector<double> numbers;  // one per quantity
  std::vector<bool> best;       // one per quantity
  int n_runs = 0;
  // Seed statistics (Tables 1, 2): numbers are the means over the seeds that finished ok, spread
  // their sample std per quantity (NaN with one ok seed), n_failed of the n_runs finished seeds
  // failed; the state is kFailed only when every finished seed failed.
  bool seed_stats = false;
  std::vector<double> spread;
  int n_failed = 0;
};

struct TableRow {
  std::string key;     // dataset or metric
  std::string label;   // paper label (+ '*' when the reference is an estimate)
  std::string frames;  // "all" | "N" (requested frames of our runs), "" for metric rows
  int ours_decimals = 3;
  int paper_decimals = 3;
  bool higher_is_better = false;
  std::string suffix;            // printed after numbers ("x" for the real-time factor)
  bool scientific = false;       // numbers as 1.2e-07 (decimals of the mantissa), not fixed
  std::vector<TableCell> ours;   // one per column
  std::vector<TableCell> paper;  // one per column
};

struct TableColumn {
  std::string variant;
  std::string label_md;   // "√VIO-64"
  std::string label_tex;  // "$\sqrt{\text{VIO}}$-64"
  int decimals = -1;      // ≥ 0: overrides the row's decimals (a column of another unit)
  std::string quantity;   // CSV quantity of this column when not the table's (e.g. "kld")
};

struct Table {
  std::string id;     // "table1"
  std::string title;  // "Table 1: absolute trajectory error [m], VIO"
  std::string row_header;
  std::vector<std::string> quantities;
  std::vector<TableColumn> columns;
  std::vector<TableRow> rows;
  std::vector<std::string> notes;
  bool has_paper = true;  // false: no paper column (a table of ours only)
};

// One sequence of the seed claim. Means and stds over the seeds that finished ok (NaN when
// none / fewer than two); paired: mean over the seeds where both finished ok of
// |ATE(√-f32) − ATE(√-f64)| (same seed: same simulated measurements).
struct SeedClaimRow {
  std::string key, label;
  int seeds_64 = 0, failed_64 = 0, seeds_32 = 0, failed_32 = 0;  // finished seeds, failed ones
  double mean_64 = 0, std_64 = 0, mean_32 = 0, std_32 = 0;
  double delta = 0;     // |mean_32 − mean_64|
  double relative = 0;  // delta / mean_64 (the paper's "within 1 %")
  double paired = 0;
  // "yes": delta ≤ std_64; "no": delta > std_64, or √-f32 failed on a seed; "–": fewer than two
  // ok √-f64 seeds (no spread) or no ok √-f32 seed.
  std::string verdict;
};

struct SeedClaim {
  std::string id = "seed_claim";
  std::string title;
  std::vector<SeedClaimRow> rows;
  std::vector<std::string> notes;
};

struct TableSet {
  std::string override_name;         // "" for runs without override
  std::vector<Table> tables;         // only tables with at least one row of ours
  std::vector<std::string> skipped;  // why a table is absent
  std::optional<SeedClaim> claim;    // when Table 1 or 2 has seed statistics
};

// Seed statistics of Tables 1 and 2: kAuto turns them on for a table when one of its cells holds
// more than one seed.
enum class SeedStats { kAuto, kOn, kOff };
// False for a name other than "auto", "on", "off".
bool parseSeedStats(const std::string& text, SeedStats* mode);

// The published tables (publishedTables(), table_specs.h) of the runs, one set per override.
std::vector<TableSet> buildTables(const ResultSet& results, const PaperValues& paper,
                                  SeedStats seeds = SeedStats::kAuto);

std::string renderMarkdown(const Table& table);
std::string renderLatex(const Table& table);
std::string renderCsv(const std::vector<Table>& tables, const std::string& override_name);
std::string renderMarkdown(const SeedClaim& claim);
std::string renderLatex(const SeedClaim& claim);
std::string renderCsv(const SeedClaim& claim, const std::string& override_name);
// A number as the tables print it: fixed decimals (or scientific), "x" for failures, "–" for
// missing.
std::string formatCell(const TableCell& cell, std::size_t component, int decimals,
                       const std::string& suffix, bool scientific = false);

// ---- files --------------------------------------------------------------------------------------

struct TablesRequest {
  std::vector<std::string> dirs;
  std::string formats = "md,tex,csv";
  std::string out;           // default <first dir>/tables
  std::string paper_values;  // default defaultPaperValuesPath()
  SeedStats seeds = SeedStats::kAuto;
  bool print = false;
  // `marglab tables`: runs none of whose tables can be made are an InputError (before anything is
  // written), not an exit 0 without a table; the notebooks and the report accept them.
  bool require_tables = false;
};

// Reads the results of the folders and writes, per override set, tables[__<override>].{md,tex,csv}
// (all tables) and table<N>[__<override>].{md,tex,csv}; prints one line per set to stdout and
// warnings to stderr; returns the combined files. Throws UsageError / InputError.
std::vector<std::string> writeTables(const TablesRequest& request, std::string* markdown);

}  // namespace marglab::experiment
