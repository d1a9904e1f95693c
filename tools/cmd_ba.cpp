// `marglab ba`: one solver on one BAL bundle-adjustment problem → one HDF5 results file
// (docs/bundle_adjustment.md). The elimination ablation ns-f32 / ns-f64 / sc-f32 / sc-f64 and the
// Ceres peers on the same model, start and loss (core/ba/ba_solver.h).

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <memory>

#include "core/ba/ba_results.h"
#include "core/ba/ba_run_spec.h"
#include "core/ba/ba_solver.h"
#include "core/ba/bal_problem.h"
#include "core/ba/ceres_ba.h"
#include "core/bench/isa_choice.h"
#include "core/common/error.h"
#include "core/linalg/isa.h"
#include "tools/command.h"
#include "tools/option_checks.h"
#include "tools/output_checks.h"

namespace marglab {
namespace {

struct BaArgs {
  std::string spec_file;
  std::string solver;
  bool json = false;
  BaRunSpec spec;  // the options bound directly (problem, settings, output)
};

void addOptions(CLI::App& sub, BaArgs& a) {
  BaOptions& o = a.spec.options;
  sub.add_option("--spec", a.spec_file,
                 "run this ba spec file (core/ba/ba_run_spec.h; a sweep writes one per run); only "
                 "-o and --json beside it")
      ->check(cli::existingPath("--spec", cli::PathKind::kFile));
  sub.add_option("--problem", a.spec.problem, "a BAL problem file, plain or .bz2 (datasets/bal/)")
      ->check(cli::existingPath("--problem", cli::PathKind::kFile));
  sub.add_option("--solver", a.solver, fmt::format("{}", fmt::join(baSolverNames(), " | ")));
  sub.add_option("--iterations", o.iterations,
                 "LM iterations, every trial counted (rootba's default 20)");
  sub.add_option("--huber", o.huber_px, "Huber threshold in pixels (0: no robust loss)");
  sub.add_option("--perturb", o.perturb_sigma,
                 "σ of the perturbation of camera centres and points (after --normalize)");
  sub.add_option("--seed", o.seed, "seed of the perturbation (rootba's 38401)");
  sub.add_option("--normalize", o.normalize_scale,
                 "normalize the scene to this median absolute deviation (rootba: 100; 0: off)");
  sub.add_option("--threads", o.threads,
                 "threads: ns / sc linearize and multiply over the landmark blocks in parallel "
                 "(the same numbers for every count); Ceres' num_threads");
  sub.add_option("--isa", a.spec.isa,
                 "instruction set of the ns / sc kernels (auto: the fastest on this machine, "
                 "measured once per CPU and build and cached; docs/design.md §ISA dispatch); "
                 "recorded in the results file's isa and isa_choice attributes")
      ->check(CLI::IsMember({"auto", "sse2", "avx2", "avx512"}))
      ->capture_default_str();
  sub.add_flag("--json", a.json, "print the result as one JSON object");
  sub.add_option("-o,--output", a.spec.output, "the HDF5 results file to write");
  sub.final_callback([&sub, &a] {
    if (a.spec_file.empty()) return;
    for (const CLI::Option* option : sub.get_options()) {
      const std::string name = option->get_name();
      if (option->count() == 0 || name == "--spec" || name == "--output" || name == "--json" ||
          name == "--help") {
        continue;
      }
      // Thrown while parsing: a CLI11 error, reported like any other bad option (exit 2).
      throw CLI::ValidationError(
          "--spec",
          fmt::format("FILE gives the whole run: {} cannot be given beside it (only -o, --json)",
                      name));
    }
  });
}

// The run's spec: from --spec FILE (a -o beside it replaces its output), or from the options.
BaRunSpec specOf(const BaArgs& a) {
  if (!a.spec_file.empty()) {
    BaRunSpec spec = BaRunSpec::fromTomlFile(a.spec_file);
    if (!a.spec.output.empty()) spec.output = a.spec.output;
    return spec;
  }
  if (a.spec.problem.empty()) throw UsageError("--problem is required (or --spec FILE)");
  if (a.solver.empty()) throw UsageError("--solver is required (or --spec FILE)");
  if (a.spec.output.empty()) throw UsageError("-o is required: the results file to write");
  BaRunSpec spec = a.spec;
  spec.options.solver = parseBaSolver(a.solver);
  return spec;
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

int runBa(const BaArgs& a) {
  const BaRunSpec spec = specOf(a);
  const std::vector<Problem> problems = baRunProblems(spec);
  if (!problems.empty()) throwProblems(problems);
  cli::checkOutputFile(spec.output, "-o");
  cli::refuseOverwritingInputs({spec.output}, {{spec.problem, a.spec_file}, {}});
  resolveIsa(spec.isa);  // the name and the CPU, before any work
  BalProblem problem = loadBalProblem(spec.problem);
  const BaOptions& o = spec.options;
  if (o.normalize_scale > 0) normalizeBalProblem(&problem, o.normalize_scale);
  if (o.perturb_sigma > 0) perturbBalProblem(&problem, o.perturb_sigma, o.seed);
  activateIsa(spec.isa);         // `auto` measures once per machine and build
  keepCeresWarningsOffStderr();  // recorded per step in /iterations messages instead
  BaRunRecord run;
  run.problem_file = spec.problem;
  run.problem = &problem;
  run.options = o;
  run.result = solveBundleAdjustment(problem, o);
  run.peak_rss_mb = peakResidentMb();
  writeBaResults(spec.output, run);
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
