// Tables as data (table_specs.h): a new study's table is one declarative TableSpec — columns,
// quantity, seed statistics, rows, notes — and the one builder makes it from runs without a change
// of its own. Two small specs over synthetic runs (in memory, no results files): a per-sequence
// table with seed statistics of a quantity the published tables do not have, beside an optional
// reference column and a column group; and an averages table with a ratio-of-sums metric. Every
// cell, bold mark and note is checked against the value computed here from the runs.

#include <gtest/gtest.h>

#include <fmt/core.h>

#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "core/experiment/table_specs.h"
#include "core/experiment/tables.h"

namespace marglab::experiment {
namespace {

RunRecord run(const std::string& dataset, const std::string& variant, int seed, double ate,
              RunRecord::State state = RunRecord::State::kOk) {
  RunRecord r;
  r.row.set("dataset", dataset);
  r.row.set("variant", variant);
  r.row.set("seed", std::to_string(seed));
  r.row.set("frames", "0");
  r.row.set("override", "");
  r.state = state;
  r.mode = dataset.rfind("kitti/", 0) == 0 ? "vo" : "vio";
  r.ate_rmse = ate;
  r.t_opt_s = 2.0 * seed;
  r.t_marg_s = 0.5;
  r.duration_s = 100;
  r.n_frames = 1000;
  return r;
}

// A quantity none of the published tables has: optimization time per frame, in milliseconds.
double msPerFrame(const RunView& r) {
  return 1e3 * r.record.t_opt_s / static_cast<double>(r.record.n_frames);
}
bool isF32(const std::string& variant) {
  return variant.size() > 4 && variant.substr(variant.size() - 3) == "f32";
}

// A spec's head: id, title, row header and one group of rows.
TableSpec head(const std::string& id, const std::string& row_header, RowGroup rows) {
  TableSpec t;
  t.id = id;
  t.title = id;
  t.row_header = row_header;
  t.rows = {std::move(rows)};
  return t;
}

// The study: ms per frame over the seeds, the √-f64 reference (when it ran) beside every f32
// variant, EuRoC rows in the order of paper table "t", then by name.
TableSpec studySpec() {
  TableSpec t = head("study", "sequence", {Family::kEuroc, "t"});
  t.title = "Study: optimization time per frame [ms]";
  ColumnSpec reference;
  reference.key = "ns-qr-sqrt-f64";
  reference.label_md = "√-64";
  reference.defines_rows = false;
  reference.optional = true;
  ColumnSpec group;
  group.matching = isF32;
  group.order = {"sc-sc-sq-f32"};
  t.columns = {reference, group};
  t.quantities = {{"ms_per_frame", msPerFrame}};
  t.cell = CellStat::kSeeds;
  t.ours_decimals = 2;
  t.notes = {{NoteKind::kText, "Time per frame.", ""}, {NoteKind::kMode, " Simulated.", ""}};
  t.skipped = "Study: no runs of {columns}";
  return t;
}

PaperValues paperWithRowOrder() {
  PaperValues paper;
  PaperTable t;
  t.id = "t";
  for (const char* key : {"euroc/V1_01_easy", "euroc/MH_01_easy"}) {
    PaperTable::Row row;
    row.key = key;
    row.label = std::string("paper ") + key;
    t.rows.push_back(row);
  }
  paper.tables["t"] = t;
  return paper;
}

TEST(TableSpecs, ANewPerSequenceSpecIsOneEntry) {
  ResultSet runs;
  for (int seed = 1; seed <= 3; ++seed) {
    runs.runs.push_back(run("euroc/MH_01_easy", "ns-qr-sqrt-f64", seed, 0.1));
    runs.runs.push_back(run("euroc/MH_01_easy", "ns-qr-sqrt-f32", seed, 0.1));
    runs.runs.push_back(run("euroc/V1_01_easy", "ns-qr-sqrt-f32", seed, 0.2));
    runs.runs.push_back(run("euroc/V1_01_easy", "sc-sc-sq-f32", seed, 0.3,
                            seed == 2 ? RunRecord::State::kFailed : RunRecord::State::kOk));
    runs.runs.push_back(run("kitti/00", "ns-qr-sqrt-f32", seed, 0.4));  // not EuRoC: no row
  }
  const std::vector<TableSet> sets =
      buildTables(runs, paperWithRowOrder(), SeedStats::kAuto, {studySpec()}, {});
  ASSERT_EQ(sets.size(), 1u);
  ASSERT_EQ(sets[0].tables.size(), 1u);
  EXPECT_FALSE(sets[0].claim);
  const Table& t = sets[0].tables[0];
  // ms per frame of seeds 1..3: 2, 4, 6 (mean 4, sample std 2); sc-sc-sq-f32 on V1_01 lost seed 2.
  const std::string expected =
      "### Study: optimization time per frame [ms]\n\n"
      "| sequence | frames | √-64 | sc-sc-sq-f32 | ns-qr-sqrt-f32 |\n"
      "|---|---:|---:|---:|---:|\n"
      "| paper euroc/V1_01_easy | all | – | **4.00** ± 2.83 x 1/3 | **4.00** ± 2.00 |\n"
      "| paper euroc/MH_01_easy | all | **4.00** ± 2.00 | – | **4.00** ± 2.00 |\n\n"
      "Time per frame.\n"
      "Estimator mode of our runs (results attribute `mode`): vio. Simulated.\n\n";
  EXPECT_EQ(renderMarkdown(t), expected);
  EXPECT_FALSE(t.has_paper);
  EXPECT_EQ(t.rows[0].ours[1].n_failed, 1);
  EXPECT_DOUBLE_EQ(t.rows[0].ours[1].spread[0], std::sqrt(8.0));
}

TEST(TableSpecs, AnAbsentTableSaysWhyWithItsColumns) {
  ResultSet runs;
  runs.runs.push_back(run("kitti/00", "ns-qr-sqrt-f64", 1, 0.4));
  const std::vector<TableSet> sets =
      buildTables(runs, PaperValues{}, SeedStats::kAuto, {studySpec()}, {});
  ASSERT_EQ(sets.size(), 1u);
  EXPECT_TRUE(sets[0].tables.empty());
  EXPECT_EQ(sets[0].skipped, std::vector<std::string>{"Study: no runs of ns-qr-sqrt-f64"});
}

// Averages over the sequences that have every column: per sequence the mean over seeds, then the
// mean over sequences; a `per` metric is Σ value / Σ per over all those runs.
TEST(TableSpecs, ANewAveragesSpecIsOneEntry) {
  TableSpec t = head("averages", "metric", {Family::kVo, ""});
  t.layout = Layout::kAverages;
  for (const char* v : {"a-f64", "b-f32"}) {
    ColumnSpec c;
    c.key = v;
    t.columns.push_back(c);
  }
  t.quantities = {{"value"}};
  MetricSpec ate{"ate", "ATE [m]", 3, 3, false, "", nullptr, nullptr};
  ate.value = [](const RunView& r) { return r.record.ate_rmse; };
  MetricSpec speed{"speed", "frames / s opt", 1, 1, true, "x", nullptr, nullptr};
  speed.value = [](const RunView& r) { return static_cast<double>(r.record.n_frames); };
  speed.per = [](const RunView& r) { return r.record.t_opt_s; };
  t.metrics = {ate, speed};
  t.notes = {{NoteKind::kSequences, "Over {n}: {sequences}.", ""}};
  ResultSet runs;
  for (int seed = 1; seed <= 2; ++seed) {
    runs.runs.push_back(run("kitti/00", "a-f64", seed, 0.1 * seed));
    runs.runs.push_back(run("kitti/00", "b-f32", seed, 0.2));
    runs.runs.push_back(run("kitti/05", "a-f64", seed, 0.5));
    runs.runs.push_back(run("kitti/05", "b-f32", seed, 0.6));
    runs.runs.push_back(run("kitti/07", "a-f64", seed, 9.0));  // no b-f32: not averaged
  }
  const std::vector<TableSet> sets = buildTables(runs, PaperValues{}, SeedStats::kAuto, {t}, {});
  ASSERT_EQ(sets.size(), 1u);
  ASSERT_EQ(sets[0].tables.size(), 1u);
  const Table& table = sets[0].tables[0];
  ASSERT_EQ(table.rows.size(), 2u);
  // a-f64: ATE (0.15 + 0.5) / 2; b-f32 (0.2 + 0.6) / 2. Speed: 4000 frames / (2 + 4 + 2 + 4) s.
  EXPECT_DOUBLE_EQ(table.rows[0].ours[0].numbers[0], (0.15 + 0.5) / 2);
  EXPECT_DOUBLE_EQ(table.rows[0].ours[1].numbers[0], (0.2 + 0.6) / 2);
  EXPECT_TRUE(table.rows[0].ours[0].best[0]);
  EXPECT_FALSE(table.rows[0].ours[1].best[0]);
  EXPECT_DOUBLE_EQ(table.rows[1].ours[0].numbers[0], 4000.0 / 12.0);
  EXPECT_EQ(table.rows[1].ours[0].n_runs, 4);
  EXPECT_TRUE(table.rows[1].ours[0].best[0] && table.rows[1].ours[1].best[0]);  // higher, tied
  EXPECT_EQ(table.notes,
            std::vector<std::string>{"Over 2: kitti/00 (all frames), kitti/05 (all frames)."});
}

// A median over the seeds, printed in scientific notation, of a value only some runs have (as a
// statistic of results files that a committed folder does not keep): without any value the table
// is absent rather than a table of dashes.
TEST(TableSpecs, AMedianSpecOfValuesSomeRunsLack) {
  TableSpec t = head("median", "sequence", {Family::kVio, ""});
  ColumnSpec c;
  c.key = "v-f32";
  t.columns = {c};
  t.quantities = {{"ratio", [](const RunView& r) {
                     return r.record.ate_rmse > 1 ? std::numeric_limits<double>::quiet_NaN()
                                                  : -1e-6 * r.record.ate_rmse;
                   }}};
  t.cell = CellStat::kMedian;
  t.scientific = t.needs_files = true;
  t.ours_decimals = 1;
  t.ranked = false;
  ResultSet runs;
  for (int seed = 1; seed <= 4; ++seed) {
    runs.runs.push_back(run("euroc/MH_01_easy", "v-f32", seed, seed == 4 ? 9.0 : 0.1 * seed));
  }
  std::vector<TableSet> sets = buildTables(runs, PaperValues{}, SeedStats::kAuto, {t}, {});
  ASSERT_EQ(sets.size(), 1u);
  ASSERT_EQ(sets[0].tables.size(), 1u);
  const TableCell& cell = sets[0].tables[0].rows.at(0).ours.at(0);
  EXPECT_EQ(cell.n_runs, 3);  // the seed without a value is left out
  EXPECT_DOUBLE_EQ(cell.numbers.at(0), -1e-6 * 0.2);
  EXPECT_NE(renderMarkdown(sets[0].tables[0]).find("| euroc/MH_01_easy | all | -2.0e-07 |"),
            std::string::npos)
      << renderMarkdown(sets[0].tables[0]);
  for (RunRecord& r : runs.runs) r.ate_rmse = 9.0;
  sets = buildTables(runs, PaperValues{}, SeedStats::kAuto, {t}, {});
  ASSERT_EQ(sets.size(), 1u);
  EXPECT_TRUE(sets[0].tables.empty());
}

}  // namespace
}  // namespace marglab::experiment
