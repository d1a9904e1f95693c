// The project's tables as data (table_specs.h): one entry per published table, read by the
// generic builder of table_builder.cpp. Texts are the tables' own (titles, labels, notes).

#include "core/experiment/table_specs.h"

#include "core/common/error.h"
#include "core/estimator/marg_prior.h"
#include "core/estimator/variant.h"

namespace marglab::experiment {

namespace {

// ---- what a cell reads from a run ---------------------------------------------------------------

double ate(const RunView& r) { return r.record.ate_rmse; }
double tOpt(const RunView& r) { return r.record.t_opt_s; }
double tMarg(const RunView& r) { return r.record.t_marg_s; }
double tTotal(const RunView& r) { return r.record.t_opt_s + r.record.t_marg_s; }
double duration(const RunView& r) { return r.record.duration_s; }
double kld(const RunView& r) { return r.file().kld_mean; }
double nnzRatio(const RunView& r) { return r.file().nnz_ratio; }
double optMean(const RunView& r) { return r.file().opt.mean; }
double optRmse(const RunView& r) { return r.file().opt.rmse; }
double optStd(const RunView& r) { return r.file().opt.std; }
double margMean(const RunView& r) { return r.file().marg.mean; }
double margRmse(const RunView& r) { return r.file().marg.rmse; }
double margStd(const RunView& r) { return r.file().marg.std; }
double worstSigmaRatio(const RunView& r) { return r.file().worst_sigma_ratio; }

// A variant whose prior storage is preconditioned (sqp, sqj, sqrtp:
// docs/preconditioned_storage.md).
bool isPreconditioned(const std::string& variant) {
  try {
    return preconditioningOf(Variant::parse(variant).storage) != Preconditioning::kNone;
  } catch (const UsageError&) {
    return false;
  }
}

// ---- shared texts -------------------------------------------------------------------------------

const char* const kBold =
    "Bold: best of the row among ours and among the paper's values (as printed); x: failed; –: "
    "no run.";
const char* const kAteNote =
    "ATE: RMSE of the positions after SE(3) alignment to the reference, in metres (results "
    "/summary ate_rmse).";
const char* const kRuntimeNote =
    "Total wall time of optimization / marginalization in seconds (results /summary "
    "t_opt_total_s / t_marg_total_s); diagnostics are not timed.";
const char* const kSeedNote =
    "Seeds: mean ± sample standard deviation of the ATE over the seeds whose run finished ok; "
    "`x k/n`: k of the n finished seeds failed (left out of the mean); the paper's value is one "
    "run.";
const char* const kEstimateNote =
    "*: the shipped reference trajectory is a VIO estimate, not ground truth; our ATE is "
    "relative to it.";
const char* const kStorages =
    "Storages (docs/preconditioned_storage.md): sq = Hessian prior, sqrt = square-root prior; "
    "sqp = Hessian prior with 3×3 block-Jacobi preconditioning (one block per physical quantity), "
    "sqj = the same with point-Jacobi scaling, sqrtp = square-root prior made by the "
    "block-preconditioned LDLT; the preconditioning also scales the LM step's LDLT.";
const char* const kWholeOnly = " Whole sequences only (runs over the first N frames are left out).";
const char* const kShortOnly =
    " Runs over the first N frames only (the whole sequences are left out).";
const char* const kNoPaper = "No paper values: the paper has no preconditioned storage.";

NoteSpec note(NoteKind kind, std::string text = "") { return {kind, std::move(text), ""}; }

ColumnSpec column(std::string key, std::string label_md = "", std::string label_tex = "") {
  ColumnSpec c;
  c.key = std::move(key);
  c.label_md = std::move(label_md);
  c.label_tex = std::move(label_tex);
  return c;
}

// The paper's four columns of Tables 1, 2, 3, 5 (√-64, √-32, SC-64, SC-32; family "VIO" or
// "VO"), and the mixed-precision variant (not in the paper) after them when it was run.
std::vector<ColumnSpec> headline(const std::string& family) {
  const std::string sqrt_tex = "$\\sqrt{\\text{" + family + "}}$";
  std::vector<ColumnSpec> columns = {
      column("ns-qr-sqrt-f64", "√" + family + "-64", sqrt_tex + "-64"),
      column("ns-qr-sqrt-f32", "√" + family + "-32", sqrt_tex + "-32"),
      column("sc-sc-sq-f64", family + "-64", "\\textit{" + family + "-64}"),
      column("sc-sc-sq-f32", family + "-32", "\\textit{" + family + "-32}"),
      column("ns-qr-sqrt-mixed", "√" + family + "-mixed", sqrt_tex + "-mixed")};
  columns.back().defines_rows = false;
  columns.back().optional = true;
  return columns;
}

// ---- Demmel et al., Tables 1–6 ------------------------------------------------------------------

// Tables 1 (VIO) and 2 (VO): ATE per sequence, with seed statistics over several seeds.
TableSpec ateTable(int number, bool vio) {
  TableSpec t;
  t.id = t.paper = "table" + std::to_string(number);
  t.title = "Table " + std::to_string(number) + ": absolute trajectory error [m], " +
            (vio ? "VIO (EuRoC, TUM-VI)" : "VO (KITTI)");
  t.row_header = "sequence";
  t.rows = {{vio ? Family::kVio : Family::kVo, t.paper}};
  t.columns = headline(vio ? "VIO" : "VO");
  t.quantities = {{"ate", ate}};
  t.cell = CellStat::kSeedsOnRequest;
  t.ours_decimals = 4;
  t.paper_decimals = vio ? 3 : 2;
  t.notes = {note(NoteKind::kText, kAteNote),
             note(NoteKind::kMode),
             note(NoteKind::kOurs),
             note(NoteKind::kSeeds, kSeedNote),
             note(NoteKind::kEstimate, kEstimateNote),
             note(NoteKind::kPaperSource),
             note(NoteKind::kPaperAbsent),
             note(NoteKind::kText, kBold)};
  t.skipped =
      "Table " + std::to_string(number) + (vio ? ": no EuRoC / TUM-VI runs" : ": no KITTI runs");
  return t;
}

// Tables 3 (VIO) and 5 (VO): optimization / marginalization time per sequence.
TableSpec runtimeTable(int number, bool vio) {
  TableSpec t = ateTable(number, vio);
  t.title = "Table " + std::to_string(number) + ": runtime [s], optimization / marginalization, " +
            (vio ? "VIO (EuRoC, TUM-VI)" : "VO (KITTI)");
  t.quantities = {{"opt", tOpt}, {"marg", tMarg}};
  t.cell = CellStat::kMean;
  t.ours_decimals = 2;
  t.paper_decimals = 1;
  t.notes[0].text = kRuntimeNote;
  t.notes[2].text = "a 12-thread Xeon W-2133";
  return t;
}

// Tables 4 (VIO on EuRoC) and 6 (VO on KITTI): the eight square-root-storage variants averaged
// over the sequences that have all of them.
TableSpec ablationTable(int number, Family family) {
  TableSpec t;
  t.id = t.paper = "table" + std::to_string(number);
  t.title = "Table " + std::to_string(number) +
            ": ablation of optimization / marginalization and precision, " +
            (number == 4 ? "VIO on EuRoC" : "VO on KITTI") +
            ", square-root prior storage (averages)";
  t.row_header = "metric";
  t.layout = Layout::kAverages;
  t.rows = {{family, ""}};
  // Optimization NS+LDLT or SC+LDLT / marginalization NS+QR or SC+SC, precision.
  for (const auto& [variant, label] : {std::pair{"ns-qr-sqrt-f64", "NS/QR-64"},
                                       {"ns-qr-sqrt-f32", "NS/QR-32"},
                                       {"sc-qr-sqrt-f64", "SC/QR-64"},
                                       {"sc-qr-sqrt-f32", "SC/QR-32"},
                                       {"ns-sc-sqrt-f64", "NS/SC-64"},
                                       {"ns-sc-sqrt-f32", "NS/SC-32"},
                                       {"sc-sc-sqrt-f64", "SC/SC-64"},
                                       {"sc-sc-sqrt-f32", "SC/SC-32"}}) {
    t.columns.push_back(column(variant, label, label));
  }
  t.quantities = {{"value"}};
  t.metrics = {{"ate_m", "ATE [m]", 4, 3, false, "", ate},
               {"realtime", "real-time", 1, 1, true, "x", duration, tTotal},
               {"t_total_s", "t total [s]", 2, 1, false, "", tTotal},
               {"t_opt_s", "t opt [s]", 2, 1, false, "", tOpt},
               {"t_marg_s", "t marg [s]", 2, 1, false, "", tMarg}};
  t.notes = {
      note(
          NoteKind::kSequences,
          "Columns: optimization / marginalization - precision; NS = nullspace projection "
          "(NS+LDLT, NS+QR), SC = Schur complement (SC+LDLT, SC+SC); all store the prior in square "
          "root form. Ours: averages over {n} sequence(s) that have all eight variants: "
          "{sequences}."),
      note(NoteKind::kText,
           "t total = t opt + t marg (our front-end is simulated and not timed); real-time = "
           "Σ duration / Σ t total; x: the variant failed on at least one of these sequences."),
      note(NoteKind::kMode), note(NoteKind::kPaperSource), note(NoteKind::kText, kBold)};
  t.skipped = "Table " + std::to_string(number) + ": no " + (number == 4 ? "EuRoC" : "KITTI") +
              " sequence has all eight ablation variants ({columns})";
  return t;
}

// ---- the preconditioned-storage study (issue #31 §3) --------------------------------------------

enum class Study { kAte, kFailures, kSigma };

// Per sequence, each preconditioned storage that ran beside the references that ran (the paper's
// √-f32 and SC-32, and the square root of an unpreconditioned LDLT, which sqrtp preconditions):
// the ATE over the seeds, the median frame where the failed seeds stopped, or how indefinite the
// stored prior became. Whole sequences, or (short) a sweep's short group, never both in one row.
TableSpec preconditionedTable(Study study, bool short_group) {
  TableSpec t;
  const char* const ids[] = {"preconditioned", "preconditioned_failures", "preconditioned_sigma"};
  const char* const titles[] = {"absolute trajectory error [m]",
                                "median frame where the failed runs stopped",
                                "how indefinite the stored prior becomes, median σ_min/σ_max"};
  const auto s = static_cast<std::size_t>(study);
  t.id = std::string(ids[s]) + (short_group ? "_short" : "");
  t.title = std::string("Preconditioned Hessian storage: ") + titles[s] +
            (short_group ? ", the short group (first N frames)" : "");
  t.row_header = "sequence";
  t.keys = short_group ? Keys::kVariantShort : Keys::kVariantWhole;
  t.rows = {{Family::kVio, "table1"}, {Family::kVo, "table2"}};
  for (const char* reference : {"ns-qr-sqrt-f32", "sc-sc-sq-f32", "sc-sc-sqrt-f32"}) {
    ColumnSpec c = column(reference);
    c.defines_rows = false;
    c.optional = true;
    t.columns.push_back(c);
  }
  ColumnSpec group;
  group.matching = isPreconditioned;
  group.order = {"sc-sc-sqp-f32", "ns-sc-sqp-f32", "sc-sc-sqj-f32", "sc-sc-sqrtp-f32",
                 "sc-sc-sqp-f64"};
  t.columns.push_back(group);
  const char* const quantities[] = {"ate", "failure_frame", "sigma_ratio"};
  t.quantities = {{quantities[s], study == Study::kSigma ? worstSigmaRatio : ate}};
  const CellStat cells[] = {CellStat::kSeeds, CellStat::kFailureFrame, CellStat::kMedian};
  t.cell = cells[s];
  t.ours_decimals = study == Study::kFailures ? 0 : study == Study::kSigma ? 1 : 4;
  t.scientific = t.needs_files = study == Study::kSigma;
  t.ranked = study == Study::kAte;
  const char* const what[] = {
      "ATE: results /summary ate_rmse, mean ± sample standard deviation over the seeds whose run "
      "finished ok; `x k/n`: k of the n finished seeds failed (left out of the mean).",
      "Median over the seeds that failed of the frame where the run stopped (index "
      "failure_frame); –: no seed failed, or no run.",
      "σ_min/σ_max: the most negative ratio of the gauge-free prior's smallest to largest "
      "eigenvalue over the run (results /marg sigma_min, sigma_max): 0 exactly, about ±1e-7 from "
      "f32 rounding, below: an indefinite prior; median over the finished seeds whose results "
      "file is in its folder (their number: n_runs of the CSV); –: none."};
  t.notes = {note(NoteKind::kText, kStorages), note(NoteKind::kText, what[s]),
             note(NoteKind::kMode, short_group ? kShortOnly : kWholeOnly),
             note(NoteKind::kText, study == Study::kAte
                                       ? std::string("Bold: best of the row; x: failed; –: no "
                                                     "run. ") +
                                             kNoPaper
                                       : std::string(kNoPaper))};
  return t;
}

// ---- Hsiung et al. (IROS 2018), marginalization strategies --------------------------------------

// Their order of columns: theirs (nfr), the dense prior it sparsifies, OKVIS's (discard).
const std::vector<std::string> kStrategies = {"nfr", "dense", "discard"};

// What both strategy tables share: the paper's table of the same id, the EuRoC rows in its order,
// columns keyed by strategy.
TableSpec strategyTable(const std::string& id, std::string title, std::string row_header) {
  TableSpec t;
  t.id = t.paper = id;
  t.title = std::move(title);
  t.row_header = std::move(row_header);
  t.keys = Keys::kMargStrategy;
  t.rows = {{Family::kEuroc, t.paper}};
  return t;
}

// Table I analog: ATE per EuRoC sequence and strategy, the nfr runs' KLD and sparsity beside.
TableSpec strategyAccuracy() {
  TableSpec t = strategyTable(
      "sparsify_table1",
      "Table I (Hsiung et al.): absolute trajectory error [m] by marginalization strategy, "
      "{variant}",
      "sequence");
  for (const std::string& s : kStrategies) t.columns.push_back(column(s, s, s));
  for (const auto& [label, quantity, value] :
       {std::tuple<const char*, const char*, RunValue>{"KLD nfr [nats]", "kld", kld},
        {"nnz nfr / dense", "nnz_ratio", nnzRatio}}) {
    // The nfr runs' own statistics: not ranked against the ATE, no paper value.
    ColumnSpec c = column("nfr", label, label);
    c.defines_rows = c.ranked = c.paper = false;
    c.decimals = 3;
    c.quantity = quantity;
    c.value = value;
    t.columns.push_back(c);
  }
  t.quantities = {{"ate", ate}};
  t.notes = {
      note(NoteKind::kText,
           "ATE: RMSE of the positions after SE(3) alignment (results /summary ate_rmse) of the "
           "{variant} runs, by their results attribute marg_strategy."),
      {NoteKind::kSparsifyEvents,
       "KLD nfr: mean D_KL(Λ_t ‖ Λ_s) [nats] (eq. 10, /sparsify kld) over the keyframe "
       "marginalizations of the nfr runs whose recovered factors replaced the dense prior; "
       "nnz nfr / dense: mean of nnz_sparse / nnz_dense over all of them (1 where nfr kept the "
       "dense prior); here {recovered} of {events} events recovered.",
       "nfr"},
      note(NoteKind::kText,
           "Paper: Proposed beside nfr, OKVIS (ours) — OKVIS's marginalization in the authors' "
           "pipeline — beside discard; the paper has no dense column (its OKVIS, VINS-MONO* and "
           "ROVIO are in paper_values.toml)."),
      note(NoteKind::kMode),
      note(NoteKind::kOurs),
      note(NoteKind::kPaperSource),
      note(NoteKind::kPaperAbsent),
      note(NoteKind::kText, kBold)};
  return t;
}

// Table II analog: one row per sequence × strategy, the time statistics as columns, the paper's
// (Proposed) beside the nfr rows.
TableSpec strategyTiming() {
  TableSpec t = strategyTable(
      "sparsify_table2",
      "Table II (Hsiung et al.): run time [s] per optimization and per keyframe marginalization "
      "by marginalization strategy, {variant}",
      "sequence strategy");
  t.layout = Layout::kPerSequenceAndKey;
  t.row_keys = kStrategies;
  t.paper_row_key = "nfr";
  // Column keys are the paper's column ids.
  for (const auto& [key, label, value] :
       {std::tuple<const char*, const char*, RunValue>{"opt_mean", "opt mean", optMean},
        {"opt_rmse", "opt RMSE", optRmse},
        {"opt_std", "opt std", optStd},
        {"marg_mean", "marg mean", margMean},
        {"marg_rmse", "marg RMSE", margRmse},
        {"marg_std", "marg std", margStd}}) {
    ColumnSpec c = column(key, label, label);
    c.value = value;
    t.columns.push_back(c);
  }
  t.quantities = {{"time_s"}};
  t.ranked = false;
  t.notes = {
      note(
          NoteKind::kText,
          "opt: wall time of the optimization of every frame (/frames t_opt_s). marg: /frames "
          "t_marg_s of the frames that marginalized a keyframe — for dense and nfr the frames with "
          "a /sparsify row, for discard (no /sparsify rows) every keyframe from the (max_kfs + "
          "1)-th on (config [window] max_kfs), since each pushes one keyframe out of the full "
          "window; it is the frame's whole marginalization event (with the oldest state's "
          "speed-bias or non-keyframe state, ended landmark tracks and, for nfr, recovery and "
          "insertion). Mean, RMSE = √mean(t²) and population std per run, averaged over seeds."),
      note(NoteKind::kText,
           "Paper: the proposed method only (beside our nfr rows), marginalization including "
           "sparsification."),
      note(NoteKind::kMode),
      note(NoteKind::kOurs, "an Intel i7-6700"),
      note(NoteKind::kPaperSource),
      note(NoteKind::kText, "x: failed; –: no run.")};
  return t;
}

}  // namespace

bool inFamily(Family family, const std::string& dataset) {
  const auto starts = [&dataset](const char* prefix) { return dataset.rfind(prefix, 0) == 0; };
  switch (family) {
    case Family::kVio:
      return starts("euroc/") || starts("tumvi/");
    case Family::kVo:
      return starts("kitti/");
    case Family::kEuroc:
      return starts("euroc/");
  }
  return false;
}

const std::vector<TableSpec>& publishedTables() {
  static const std::vector<TableSpec> kTables = {ateTable(1, true),
                                                 ateTable(2, false),
                                                 runtimeTable(3, true),
                                                 ablationTable(4, Family::kEuroc),
                                                 runtimeTable(5, false),
                                                 ablationTable(6, Family::kVo),
                                                 preconditionedTable(Study::kAte, false),
                                                 preconditionedTable(Study::kFailures, false),
                                                 preconditionedTable(Study::kSigma, false),
                                                 preconditionedTable(Study::kAte, true),
                                                 preconditionedTable(Study::kFailures, true),
                                                 preconditionedTable(Study::kSigma, true),
                                                 strategyAccuracy(),
                                                 strategyTiming()};
  return kTables;
}

const SeedClaimSpec& publishedSeedClaim() {
  static const SeedClaimSpec kClaim = {
      "ns-qr-sqrt-f64", "ns-qr-sqrt-f32", {{Family::kVio, "table1"}, {Family::kVo, "table2"}}};
  return kClaim;
}

}  // namespace marglab::experiment
