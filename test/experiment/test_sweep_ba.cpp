// Sweeps of `marglab ba` runs (a [[group]] of kind "ba", core/experiment/sweep_def.h): the plan of
// problems × solvers × seeds with its typed specs, every mistake refused at its line before any run
// (--dry-run too), and a tiny sweep on the shipped dubrovnik problem end to end: the index holds
// each run's status and final cost as its results file does, --resume keeps them, a planned-
// differently run is redone.

#include <gtest/gtest.h>

#include <fmt/core.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/ba/ba_results.h"
#include "core/ba/bal_problem.h"
#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/experiment/sweep_def.h"
#include "core/experiment/sweep_index.h"

namespace marglab::experiment {
namespace {

namespace fs = std::filesystem;
using test::quote;
using test::readText;
using test::runCli;

std::string balDir() { return std::string(sourceDir()) + "/datasets/bal"; }

SweepPlan parseBa(const std::string& text) {
  return parseSweep(text, "sweep.toml", balDir(), ParseOptions{{}, {}, {}, true});
}

const char* const kTiny = R"(
name = "tiny"
[[group]]
name = "g"
kind = "ba"
problems = ["dubrovnik-3-7-pre.txt"]
solvers = ["ns-f32", "ceres-sparse"]
seeds = [38401, 2]
iterations = 4
huber_px = 1.0
perturb_sigma = 0.01
normalize_scale = 100
)";

TEST(SweepBa, PlansProblemsTimesSolversTimesSeedsWithTypedSpecs) {
  const SweepPlan plan = parseBa(kTiny);
  ASSERT_EQ(plan.runs.size(), 4u);
  const PlannedRun& run = plan.runs[2];
  EXPECT_EQ(run.id, "g__dubrovnik-3-7-pre__ns-f32__s2");
  ASSERT_TRUE(run.ba.has_value());
  EXPECT_EQ(run.ba->problem, balDir() + "/dubrovnik-3-7-pre.txt");
  EXPECT_EQ(run.ba->options.solver, BaSolver::kNsF32);
  EXPECT_EQ(run.ba->options.seed, 2u);
  EXPECT_EQ(run.ba->options.iterations, 4);
  EXPECT_EQ(run.ba->options.huber_px, 1.0);
  EXPECT_EQ(run.ba->options.perturb_sigma, 0.01);
  EXPECT_EQ(run.ba->options.normalize_scale, 100.0);
  EXPECT_EQ(run.ba->output, "runs/" + run.id + ".h5");
  EXPECT_EQ(run.variant, "ns-f32");
  EXPECT_EQ(run.seed, 2u);
  // The child runs the spec; the index's command is the same run as options.
  EXPECT_EQ(BaRunSpec::fromTomlString(run.spec_toml, "spec").toToml(), run.spec_toml);
  EXPECT_EQ(childArguments(run, "runs/x.h5", ""),
            (std::vector<std::string>{"ba", "--spec", "runs/" + run.id + ".spec.toml"}));
  const std::vector<std::string> args = runArguments(run, "runs/x.h5", "");
  EXPECT_EQ(args.front(), "ba");
  EXPECT_EQ(std::vector<std::string>(args.end() - 2, args.end()),
            (std::vector<std::string>{"-o", "runs/x.h5"}));
  EXPECT_EQ(plan.runs[1].id, "g__dubrovnik-3-7-pre__ceres-sparse__s38401");
}

TEST(SweepBa, DefaultsAreTheVerbsAndAllNamesEverySolver) {
  const SweepPlan plan = parseBa(R"(
name = "d"
[[group]]
name = "g"
kind = "ba"
problems = ["dubrovnik-3-7-pre.txt"]
solvers = ["all", "ns-f32"]
)");
  ASSERT_EQ(plan.runs.size(), baSolverNames().size());
  const BaOptions defaults;
  EXPECT_EQ(plan.runs.front().ba->options.seed, defaults.seed);
  EXPECT_EQ(plan.runs.front().ba->options.iterations, defaults.iterations);
  EXPECT_EQ(plan.runs.front().ba->isa, "auto");
  EXPECT_EQ(plan.runs.back().variant, "ceres-sparse");
}

// The shipped sweep plans rootba's protocol on every shipped problem, solver and five seeds.
TEST(SweepBa, TheShippedSweepIsRootbasProtocol) {
  const SweepPlan plan =
      loadSweepFile(std::string(sourceDir()) + "/experiments/bal.toml", ParseOptions{});
  int protocol = 0;
  std::set<std::uint64_t> seeds;
  std::set<std::string> problems, solvers;
  for (const PlannedRun& run : plan.runs) {
    ASSERT_TRUE(run.ba.has_value()) << run.id;
    if (run.group != "protocol") continue;
    ++protocol;
    const BaOptions& o = run.ba->options;
    EXPECT_EQ(o.iterations, 50);
    EXPECT_EQ(o.huber_px, 1.0);
    EXPECT_EQ(o.perturb_sigma, 0.01);
    EXPECT_EQ(o.normalize_scale, 100.0);
    EXPECT_EQ(o.threads, 1);
    EXPECT_EQ(run.ba->isa, "sse2");  // as results/bal was made
    seeds.insert(o.seed);
    problems.insert(balProblemName(run.ba->problem));
    solvers.insert(run.variant);
  }
  EXPECT_EQ(protocol, 4 * static_cast<int>(baSolverNames().size()) * 5);
  EXPECT_EQ(seeds.size(), 5u);
  EXPECT_EQ(seeds.count(38401), 1u);
  EXPECT_EQ(problems.size(), 4u);
  EXPECT_EQ(solvers.size(), baSolverNames().size());
}

// Each mistake is an InputError naming the sweep file and the line of the key.
void expectRefused(const std::string& from, const std::string& to, const std::string& where,
                   const std::string& what) {
  std::string text = kTiny;
  const auto at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  try {
    parseBa(text);
    FAIL() << "accepted:\n" << text;
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(where), std::string::npos) << message;
    EXPECT_NE(message.find(what), std::string::npos) << message;
  }
}

TEST(SweepBa, RefusesEachMistakeAtItsLine) {
  expectRefused("\"ceres-sparse\"", "\"ceres-spars\"", "sweep.toml:7:", "ceres-spars");
  expectRefused("huber_px = 1.0", "huber_px = -1.0", "sweep.toml:10:", "--huber -1");
  expectRefused("huber_px = 1.0", "huber_px = \"1\"", "sweep.toml:10:", "must be a number");
  expectRefused("iterations = 4", "iterations = -4", "sweep.toml:9:", "iterations");
  expectRefused("normalize_scale = 100", "threads = 0", "sweep.toml:12:", "--threads 0");
  expectRefused("normalize_scale = 100", "isa = \"avx3\"", "sweep.toml:12:", "isa must be");
  expectRefused("dubrovnik-3-7-pre.txt", "dubrovnik-3-8-pre.txt",
                "sweep.toml:6:", "no such problem file");
  expectRefused("kind = \"ba\"", "kind = \"bal\"", "sweep.toml:5:", "kind must be");
  expectRefused("seeds = [38401, 2]", "seeds = [2, 2]", "sweep.toml:8:", "listed twice");
  expectRefused("seeds = [38401, 2]", "datasets = [\"kitti/10\"]",
                "sweep.toml:8:", "unknown key 'datasets'");
  expectRefused("problems = [\"dubrovnik-3-7-pre.txt\"]",
                "problems = [\"dubrovnik-3-7-pre.txt\", \"./dubrovnik-3-7-pre.txt\"]",
                "sweep.toml:3:", "planned twice");
}

class SweepBaFolder : public test::TempDirTest {};

TEST_F(SweepBaFolder, AMalformedProblemIsNamedWithItsLineBeforeAnyRun) {
  std::ofstream(dir_ / "bad.txt") << "1 1 2\n0 0 1 2\n0 x 3 4\n0 0 0 0 0 0 500 0 0\n1 2 -5\n";
  std::string text = kTiny;
  text.replace(text.find("\"dubrovnik-3-7-pre.txt\""), 23, quote(dir_ / "bad.txt"));
  std::replace(text.begin(), text.end(), '\'', '"');
  std::ofstream(dir_ / "sweep.toml") << text;
  const auto result =
      runCli("sweep " + quote(dir_ / "sweep.toml") + " --dry-run -o " + quote(dir_ / "out"));
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_NE(result.output.find("sweep.toml:6:"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("bad.txt:3:"), std::string::npos) << result.output;
  EXPECT_FALSE(fs::exists(dir_ / "out"));
}

const IndexRow& rowOf(const std::vector<IndexRow>& rows, const std::string& id) {
  for (const IndexRow& row : rows) {
    if (row.get("id") == id) return row;
  }
  throw std::runtime_error("no row " + id);
}

TEST_F(SweepBaFolder, RunsIndexesAndResumes) {
  std::string text = kTiny;
  text.replace(text.find("\"dubrovnik-3-7-pre.txt\""), 23,
               "\"" + balDir() + "/dubrovnik-3-7-pre.txt\"");
  std::ofstream(dir_ / "sweep.toml") << text;
  const std::string sweep =
      "sweep " + quote(dir_ / "sweep.toml") + " -j 2 -o " + quote(dir_ / "out");
  const auto first = runCli(sweep);
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_NE(first.output.find("4 ok"), std::string::npos) << first.output;
  const std::vector<IndexRow> rows = readIndex((dir_ / "out" / "index.csv").string());
  ASSERT_EQ(rows.size(), 4u);
  for (const IndexRow& row : rows) {
    SCOPED_TRACE(row.get("id"));
    EXPECT_EQ(row.get("status"), "ok");
    EXPECT_EQ(row.get("kind"), "ba");
    EXPECT_EQ(row.get("ba_status"), "max_iterations");
    const BaResultsFile file = readBaResults((dir_ / "out" / row.get("results")).string());
    EXPECT_EQ(row.number("final_cost"), file.final_cost);  // %.17g: the same double
    EXPECT_EQ(row.number("initial_cost"), file.initial_cost);
    EXPECT_EQ(file.solver, row.get("variant"));
    EXPECT_EQ(std::to_string(file.seed), row.get("seed"));
    EXPECT_EQ(file.iterations.size(), 5u);
    EXPECT_LT(file.final_cost, file.initial_cost);
    EXPECT_NE(readText(dir_ / "out" / row.get("log")).find("marglab ba --spec runs/"),
              std::string::npos);
  }
  EXPECT_EQ(rowOf(rows, "g__dubrovnik-3-7-pre__ns-f32__s2").get("precision"), "f32");
  EXPECT_EQ(rowOf(rows, "g__dubrovnik-3-7-pre__ceres-sparse__s2").get("method"), "ceres");

  // --resume keeps all four; a changed setting redoes them (the fingerprint is the command).
  const auto resumed = runCli(sweep + " --resume");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
  EXPECT_NE(resumed.output.find("4 kept"), std::string::npos) << resumed.output;
  text.replace(text.find("iterations = 4"), 14, "iterations = 3");
  std::ofstream(dir_ / "sweep.toml") << text;
  const auto changed = runCli(sweep + " --resume");
  ASSERT_EQ(changed.exit_code, 0) << changed.output;
  EXPECT_EQ(changed.output.find("kept"), std::string::npos) << changed.output;
  const std::vector<IndexRow> again = readIndex((dir_ / "out" / "index.csv").string());
  const IndexRow& row = rowOf(again, "g__dubrovnik-3-7-pre__ns-f32__s2");
  EXPECT_EQ(readBaResults((dir_ / "out" / row.get("results")).string()).iterations.size(), 4u);
}

// `marglab tables` and `marglab plot` on a folder of ba runs: the comparison tables (ba_tables.h)
// and the two figures; the final-cost cell is the mean of the two seeds' results files.
TEST_F(SweepBaFolder, TablesAndFigures) {
  std::string text = kTiny;
  text.replace(text.find("\"dubrovnik-3-7-pre.txt\""), 23,
               "\"" + balDir() + "/dubrovnik-3-7-pre.txt\"");
  std::ofstream(dir_ / "sweep.toml") << text;
  const fs::path out = dir_ / "out";
  const auto sweep = runCli("sweep " + quote(dir_ / "sweep.toml") + " -j 2 -o " + quote(out));
  ASSERT_EQ(sweep.exit_code, 0) << sweep.output;
  const auto tables = runCli("tables " + quote(out));
  ASSERT_EQ(tables.exit_code, 0) << tables.output;
  const std::string md = readText(out / "tables" / "ba_g_final.md");
  ASSERT_FALSE(md.empty()) << tables.output;
  double sum = 0;
  for (const IndexRow& r : readIndex((out / "index.csv").string())) {
    if (r.get("variant") == "ceres-sparse")
      sum += readBaResults((out / r.get("results")).string()).final_cost;
  }
  const std::string expected = fmt::format("{:.6e}", sum / 2);
  EXPECT_NE(md.find("| dubrovnik-3-7-pre | "), std::string::npos) << md;
  EXPECT_NE(md.find(expected), std::string::npos) << expected << "\n" << md;
  for (const char* id : {"ba_g_tau0.1", "ba_g_tau0.01", "ba_g_tau0.001", "ba_g_speedup", "ba_g_gap",
                         "ba_g_steps", "ba_g_conditioning", "ba_g_memory"}) {
    SCOPED_TRACE(id);
    const std::string csv = readText(out / "tables" / (std::string(id) + ".csv"));
    EXPECT_NE(csv.find(std::string(id) + ",,dubrovnik-3-7-pre,"), std::string::npos) << csv;
  }
  // The final cost in the CSV is the mean of the two seeds to the last bit (%.17g).
  EXPECT_NE(readText(out / "tables" / "ba_g_final.csv")
                .find(fmt::format(",ceres-sparse,final_cost,{:.17g},ok,", sum / 2)),
            std::string::npos);
  const fs::path figures = dir_ / "figures";
  const auto plot =
      runCli("plot " + quote(out) + " --figure ba_convergence,ba_profile --out " + quote(figures));
  if (plot.output.find("no Python with matplotlib") != std::string::npos) {
    GTEST_SKIP() << "no Python with matplotlib, h5py and numpy: " << plot.output;
  }
  ASSERT_EQ(plot.exit_code, 0) << plot.output;
  for (const char* name : {"ba_convergence_g_dubrovnik-3-7-pre", "ba_profile_g"}) {
    const fs::path file = figures / (std::string(name) + ".png");
    ASSERT_TRUE(fs::is_regular_file(file)) << file << "\n" << plot.output;
    EXPECT_GT(fs::file_size(file), 5000u) << file;
  }
}

}  // namespace
}  // namespace marglab::experiment
