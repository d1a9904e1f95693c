// `marglab sweep FILE`: validates a sweep definition (experiments/*.toml), then runs every run of
// it as an isolated child process and keeps results/<name>/index.csv up to date.

#include <fmt/core.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <vector>

#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/experiment/slurm_backend.h"
#include "core/experiment/sweep_def.h"
#include "core/experiment/sweep_runner.h"
#include "core/frontend/image_folder.h"
#include "core/pipeline/run.h"
#include "core/pipeline/run_config.h"
#include "tools/command.h"
#include "tools/option_checks.h"
#include "tools/output_checks.h"
#include "tools/run_args.h"

namespace marglab {
namespace cli {

namespace {

// Every planned run validated as `marglab run` validates it (prepareRun: the same spec, the same
// runProblems), before any run starts — `--dry-run` included. A dataset (and a track file) is
// loaded once for all the runs on it.
class PlanValidator {
 public:
  std::string check(experiment::PlannedRun* run) {
    try {
      const RunSpec spec = plannedSpec(*run);
      const RunInputs& inputs = inputsOf(spec);
      const RunSpec resolved =
          resolveRunSpec(spec, inputs.dataset.sequence, inputs.has_ground_truth);
      std::vector<Problem> problems = runProblems(resolved, inputs);
      addSharedTracksProblem(*run, spec, &problems);
      if (!problems.empty()) throwProblems(problems);
      run->spec_toml = childSpec(spec, *run).toToml();
    } catch (const InputError& e) {
      return e.what();
    } catch (const UsageError& e) {
      return e.what();
    }
    return {};
  }

 private:
  // The run's spec as its child will build it. Frontend "images": the runner tracks the images
  // into the sweep folder before the runs start, so the run is checked as an images run.
  static RunSpec plannedSpec(const experiment::PlannedRun& run) {
    experiment::PlannedRun planned = run;
    if (run.frontend == FrontendKind::kImages) planned.frontend.reset();
    planned.config_toml.clear();  // given as text below, not as the file the runner writes
    std::vector<std::string> arguments = experiment::runArguments(planned, "runs/x.h5", "");
    arguments.erase(arguments.begin());  // "run"
    RunSpec spec = parseRunArguments(arguments, run.config_toml, "the merged config of " + run.id);
    if (run.frontend == FrontendKind::kImages) spec.frontend = FrontendKind::kImages;
    return spec;
  }

  // Frontend "images": the runner tracks each dataset once, with the default front-end and
  // calibration, for every run on it; a run whose config sets [frontend] or [calibration] keys
  // would be estimated on tracks made without them.
  static void addSharedTracksProblem(const experiment::PlannedRun& run, const RunSpec& spec,
                                     std::vector<Problem>* problems) {
    if (run.frontend != FrontendKind::kImages) return;
    if (spec.config.trackingToml() == RunConfig().trackingToml()) return;
    problems->push_back(
        {ProblemKind::kUsage, "", 0,
         "frontend = \"images\" tracks each dataset's images once, with the default [frontend] "
         "and [calibration] keys, and this run's config sets some of them: leave frontend unset "
         "(each run then tracks its images itself, with its config)"});
  }

  // The spec as its child runs it, in the sweep folder: its results file, and for frontend
  // "images" the track file the runner writes before the runs.
  static RunSpec childSpec(RunSpec spec, const experiment::PlannedRun& run) {
    spec.output = "runs/" + run.id + ".h5";
    if (run.frontend == FrontendKind::kImages) {
      spec.frontend = FrontendKind::kAuto;
      spec.tracks_file = experiment::sweepTrackFile(run);
    }
    return spec;
  }

  const RunInputs& inputsOf(const RunSpec& spec) {
    const std::string key = spec.dataset + '\n' + spec.tracks_file;
    auto it = loaded_.find(key);
    if (it == loaded_.end()) {
      Loaded entry;
      // A track file that is not a regular file (a FIFO) can be read once: by its run.
      RunSpec loaded = spec;
      std::error_code ec;
      if (!std::filesystem::is_regular_file(spec.tracks_file, ec)) loaded.tracks_file.clear();
      try {
        entry.inputs = std::make_shared<RunInputs>(loadRunInputs(loaded));
      } catch (const InputError& e) {
        entry.error = std::make_shared<InputError>(e);
      }
      it = loaded_.emplace(key, std::move(entry)).first;
    }
    if (it->second.error) throw *it->second.error;
    return *it->second.inputs;
  }

  struct Loaded {
    std::shared_ptr<RunInputs> inputs;
    std::shared_ptr<InputError> error;
  };
  std::map<std::string, Loaded> loaded_;
};

}  // namespace

// The sweep's checks of its runs (also used by `marglab reproduce`): a group's `args` parsed with
// the options of `marglab run` (so that a typo names the line of `args`), and every planned run
// validated as `marglab run` would validate it.
experiment::ParseOptions sweepParseOptions() {
  experiment::ParseOptions options;
  options.check_run_args = runOptionsProblem;
  auto validator = std::make_shared<PlanValidator>();
  options.check_run = [validator](experiment::PlannedRun* run) { return validator->check(run); };
  return options;
}

}  // namespace cli

namespace {

struct SweepArgs {
  std::string file;
  int jobs = 0;
  bool resume = false;
  bool force = false;
  bool dry_run = false;
  std::string out;
  std::string backend = "local";
  std::string status_dir;
  std::vector<std::uint64_t> seeds;
  bool wait = false;
  experiment::SlurmOptions slurm;
};

// The sweep writes index.csv and .lock and fills (or, with --force, empties) its subfolders: none
// of them may hold the sweep file or a dataset of its runs.
void refuseOverwritingInputs(const experiment::SweepPlan& plan, const std::string& file,
                             const std::filesystem::path& out) {
  std::vector<std::string> inputs{file};
  for (const auto& run : plan.runs) {
    if (run.ba || std::filesystem::is_directory(run.dataset)) inputs.push_back(run.dataset);
  }
  for (const std::string& input : inputs) {
    for (const char* sub : {"runs", "logs", "configs", "slurm", "tracks"}) {
      if (cli::isInsideFolder(input, out / sub)) {
        throw InputError(input, 0,
                         fmt::format("an input of this sweep lies in {}, which the sweep writes "
                                     "and --force empties: move it elsewhere",
                                     (out / sub).string()));
      }
    }
  }
  // Every file the sweep writes lies in out: out must not be a dataset's folder or lie in one.
  cli::CommandInputs read{{file}, {}};
  std::set<std::string> datasets;
  for (const auto& run : plan.runs) {
    if (!datasets.insert(run.dataset).second) continue;
    cli::addInputs(
        &read, run.ba ? cli::CommandInputs{{run.dataset}, {}} : cli::datasetInputs(run.dataset));
  }
  cli::refuseOverwritingInputs({(out / "index.csv").string(), (out / ".lock").string()}, read);
}

// --seeds: one part of a sweep too long for one sitting (README, "A sweep folder"): only the runs
// of these seeds, each a seed the sweep file plans.
void keepSeeds(experiment::SweepPlan* plan, const std::vector<std::uint64_t>& seeds) {
  if (seeds.empty()) return;
  for (const std::uint64_t seed : seeds) {
    if (std::none_of(plan->runs.begin(), plan->runs.end(),
                     [&](const auto& run) { return run.seed == seed; })) {
      throw InputError(plan->source_file, 0,
                       fmt::format("--seeds: no run of this sweep has seed {}", seed));
    }
  }
  plan->runs.erase(std::remove_if(plan->runs.begin(), plan->runs.end(),
                                  [&](const auto& run) {
                                    return std::find(seeds.begin(), seeds.end(), run.seed) ==
                                           seeds.end();
                                  }),
                   plan->runs.end());
}

int runSweepCommand(SweepArgs args) {
  args.slurm.wait = args.wait;
  if (!args.status_dir.empty()) {
    experiment::SweepOptions options;
    options.slurm = args.slurm;
    options.status_line = cli::stderrIsTerminal();
    return experiment::slurmSweepStatus(args.status_dir, options);
  }
  if (args.file.empty()) throw UsageError("sweep: a sweep file is required (or --status DIR)");
  experiment::SweepPlan plan = experiment::loadSweepFile(args.file, cli::sweepParseOptions());
  keepSeeds(&plan, args.seeds);
  const std::string out = args.out.empty() ? "results/" + plan.name : args.out;
  if (args.dry_run) {
    fmt::print("sweep {} ({}): {} runs, would write {}\n", plan.name, args.file, plan.runs.size(),
               out);
    for (const auto& run : plan.runs) {
      fmt::print("  {}\n    marglab {}\n", run.id,
                 experiment::shellJoin(experiment::runArguments(
                     run, "runs/" + run.id + ".h5",
                     run.config_toml.empty() ? "" : "configs/" + run.id + ".toml")));
    }
    return 0;
  }
  refuseOverwritingInputs(plan, args.file, out);
  experiment::SweepOptions options;
  options.out_dir = out;
  options.jobs = args.jobs;
  options.resume = args.resume;
  options.force = args.force;
  options.status_line = cli::stderrIsTerminal();
  options.backend = args.backend;
  options.slurm = args.slurm;
  return experiment::runSweepAndReport(plan, args.file, options);
}

const bool kRegistered = cli::registerCommand(
    {"sweep", "Run a sweep definition (experiments/*.toml): every run isolated, indexed", 20,
     [](CLI::App& sub) -> cli::CommandRun {
       auto args = std::make_shared<SweepArgs>();
       sub.add_option("file", args->file, "Sweep definition (TOML), e.g. experiments/quick.toml")
           ->check(cli::existingPath("sweep file", cli::PathKind::kFile));
       sub.add_option("-j,--jobs", args->jobs, "Runs in parallel (0: number of cores)")
           ->capture_default_str()
           ->check(cli::jobCount());
       sub.add_flag("--resume", args->resume,
                    "Keep runs whose results file is complete and planned the same; redo the rest");
       sub.add_flag("--force", args->force, "Discard an earlier sweep in the output folder")
           ->excludes("--resume");
       sub.add_option("-o,--out", args->out, "Output folder (default: results/<sweep name>)");
       sub.add_flag("--dry-run", args->dry_run, "Validate and list the runs without running them");
       sub.add_option("--seeds", args->seeds,
                      "Only the runs of these seeds (comma-separated), e.g. one part of a long "
                      "sweep per folder (-o)")
           ->delimiter(',')
           ->allow_extra_args(false);
       sub.add_option("--backend", args->backend,
                      "local: child processes here; slurm: one Slurm job array (shared filesystem)")
           ->capture_default_str()
           ->check(CLI::IsMember({"local", "slurm"}));
       sub.add_flag("--wait", args->wait,
                    "slurm: follow the array until it ends (default: return after submission)");
       sub.add_option("--status", args->status_dir,
                      "Reconcile a sweep folder's index with Slurm and print where it stands")
           ->check(cli::existingPath("--status", cli::PathKind::kFolder))
           ->excludes("file");
       sub.add_option("--slurm-partition", args->slurm.partition, "slurm: --partition");
       sub.add_option("--slurm-time", args->slurm.time,
                      "slurm: --time of every task (default: the group's timeout_s, in minutes)");
       sub.add_option("--slurm-mem", args->slurm.mem, "slurm: --mem of every task, e.g. 4G");
       sub.add_option("--slurm-cpus", args->slurm.cpus, "slurm: --cpus-per-task")
           ->capture_default_str()
           ->check(cli::positiveInt("the number of CPUs"));
       sub.add_option("--slurm-arg", args->slurm.extra,
                      "slurm: a further sbatch option, verbatim (repeatable; write "
                      "--slurm-arg=--qos=long)")
           ->allow_extra_args(false);
       std::vector<const CLI::Option*> slurm_only;
       for (const char* name : {"--wait", "--slurm-partition", "--slurm-time", "--slurm-mem",
                                "--slurm-cpus", "--slurm-arg"}) {
         slurm_only.push_back(sub.get_option(name));
       }
       return [args, slurm_only] {
         for (const CLI::Option* option : slurm_only) {
           if (option->count() > 0 && args->backend != "slurm" && args->status_dir.empty()) {
             throw UsageError(option->get_name() + " is an option of --backend slurm");
           }
         }
         return runSweepCommand(*args);
       };
     }});

}  // namespace
}  // namespace marglab
