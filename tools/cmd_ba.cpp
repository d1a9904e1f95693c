// `marglab ba`: one solver on one BAL bundle-adjustment problem → one HDF5 results file
// (docs/bundle_adjustment.md). The elimination ablation ns-f32 / ns-f64 / sc-f32 / sc-f64 and the
// Ceres peers on the same model, start and loss (core/ba/ba_solver.h).

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <memory>

#include "core/ba/ba_results.h"
#include "core/ba/ba_solver.h"
#include "core/ba/bal_problem.h"
#include "core/common/error.h"
#include "tools/command.h"
#include "tools/option_checks.h"
#include "tools/output_checks.h"

namespace marglab {
namespace {

struct BaArgs {
  std::string problem;
  std::string solver;
  std::string output;
  bool json = false;
  BaOptions options;
};

void addOptions(CLI::App& sub, BaArgs& a) {
  sub.add_option("--problem", a.problem, "a BAL problem file, plain or .bz2 (datasets/bal/)")
      ->required()
      ->check(cli::existingPath("--problem", cli::PathKind::kFile));
  sub.add_option("--solver", a.solver, fmt::format("{}", fmt::join(baSolverNames(), " | ")))
      ->required();
  sub.add_option("--iterations", a.options.iterations,
                 "LM iterations, every trial counted (rootba's default 20)");
  sub.add_option("--huber", a.options.huber_px, "Huber threshold in pixels (0: no robust loss)");
  sub.add_option("--perturb", a.options.perturb_sigma,
                 "σ of the perturbation of camera centres and points (after --normalize)");
  sub.add_option("--seed", a.options.seed, "seed of the perturbation (rootba's 38401)");
  sub.add_option("--normalize", a.options.normalize_scale,
                 "normalize the scene to this median absolute deviation (rootba: 100; 0: off)");
  sub.add_option("--threads", a.options.threads, "threads (Ceres; ns / sc run on one)");
  sub.add_flag("--json", a.json, "print the result as one JSON object");
  sub.add_option("-o,--output", a.output, "the HDF5 results file to write")->required();
}

void printSummary(const BaRunRecord& run) {
  const BaResult& r = run.result;
  fmt::print("marglab ba: {} ({} cameras, {} points, {} observations), {}\n", run.problem->name,
             run.problem->numCameras(), run.problem->numPoints(), run.problem->numObservations(),
             toString(run.options.solver));
  fmt::print("  cost       {:.10e} -> {:.10e} in {} iterations, {:.3f} s\n", r.initial_cost,
             r.final_cost, r.iterations.size() - 1, r.total_time_s);
  fmt::print("  status     {}{}\n", r.status, r.reason.empty() ? "" : " (" + r.reason + ")");
  fmt::print("  behind     {} observations behind their camera (initial), {} (final)\n",
             r.num_behind_initial, r.num_behind_final);
  fmt::print("  peak RSS   {:.1f} MB\n", run.peak_rss_mb);
}

int runBa(BaArgs& a) {
  a.options.solver = parseBaSolver(a.solver);
  const std::vector<Problem> problems = validate(a.options);
  if (!problems.empty()) throwProblems(problems);
  cli::checkOutputFile(a.output, "-o");
  cli::refuseOverwritingInputs({a.output}, {{a.problem}, {}});
  BalProblem problem = loadBalProblem(a.problem);
  if (a.options.normalize_scale > 0) normalizeBalProblem(&problem, a.options.normalize_scale);
  if (a.options.perturb_sigma > 0) {
    perturbBalProblem(&problem, a.options.perturb_sigma, a.options.seed);
  }
  BaRunRecord run;
  run.problem_file = a.problem;
  run.problem = &problem;
  run.options = a.options;
  run.result = solveBundleAdjustment(problem, a.options);
  run.peak_rss_mb = peakResidentMb();
  writeBaResults(a.output, run);
  if (a.json) {
    fmt::print("{}\n", baResultJson(run).dump());
  } else {
    printSummary(run);
  }
  return 0;
}

const bool kRegistered = cli::registerCommand(
    {"ba", "Bundle adjustment of a BAL problem: ns / sc elimination in f32 / f64, Ceres peers", 65,
     [](CLI::App& sub) -> cli::CommandRun {
       auto args = std::make_shared<BaArgs>();
       addOptions(sub, *args);
       return [args] { return runBa(*args); };
     }});

}  // namespace
}  // namespace marglab
