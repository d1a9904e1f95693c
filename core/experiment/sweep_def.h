#pragma once
// Sweep definitions (experiments/*.toml) and their expansion into a run plan.
//
// A sweep is a named list of groups; each group is the cross product
//   datasets × variants × seeds × overrides
// of `marglab run` invocations. Every run of the plan gets a stable id
//   <group>__<dataset slug>__<variant>__s<seed>[__<override>]
// (dataset slug: "kitti/10" → "kitti-10"), which names its results file, log and config.
//
//   name        = "quick"                       # required; default output folder results/<name>
//   description = "..."                         # optional
//   [[group]]
//   name        = "vo"                          # required, [A-Za-z0-9_.-]+
//   datasets    = ["kitti/10", "kitti/05"]      # shipped names (`marglab datasets list`) or
//   folders
//                                               # (relative to the sweep file)
//   variants    = ["headline", "sc-qr-sqrt-f32"] # variant names or sets: paper (10), headline (4:
//                                               # ns-qr-sqrt, sc-sc-sq × f32/f64), ablation (8:
//                                               # the square-root-storage variants of Tables 4/6),
//                                               # preconditioned (docs/preconditioned_storage.md)
//   seeds       = [1]                           # optional, default [1]
//   frames      = 600                           # optional, 0 (default): the whole sequence
//   timeout_s   = 0                             # optional wall-time limit per run (0: none)
//   args        = ["--no-diagnostics"]          # optional extra `marglab run` options
//   set         = ["lm.max_iterations=3"]       # optional config keys, as `marglab run --set`
//   frontend    = "images"                      # optional: images | simulated | auto (the run's
//                                               # --frontend; default: not passed = auto). With
//                                               # "images" the runner tracks each dataset's
//                                               # images once (`marglab datasets track` →
//                                               # tracks/<dataset slug>.h5 in the sweep folder)
//                                               # and every run reads them (--tracks)
//   config_file = "my.toml"                     # optional estimator config (relative to the file)
//   [group.config]                              # optional inline config overrides, same layout
//   lm = { max_iterations = 5 }                 # as `marglab run --config` (RunConfig)
//   [[group.override]]                          # optional; without, one unnamed override
//   name   = "relqr"                            # required in an override
//   args   = ["--qr-threshold-mode", "relative"]
//   set    = ["marginalization.psd_hessian_prior=true"]
//   config = { marginalization = { qr_threshold = 1e-6 } }
//
// Everything is validated when the file is read — unknown keys, wrong types, unknown variants and
// datasets, `run` options that `marglab run` rejects, config keys RunConfig rejects,
// duplicate run ids, and (ParseOptions::check_run; the CLI's is runProblems, as `marglab run`
// validates) every planned run with its dataset — and each error is an InputError naming the file
// and line, so that no run starts from a broken sweep and no run is started that would be refused. Config layers merge as: config_file < group config < override config
// (tables merged key by key) and reach the run as one --config file.
//
// A group of `marglab ba` runs (bundle adjustment of BAL problems, docs/bundle_adjustment.md) is
// the cross product problems × solvers × seeds, with the settings of every run:
//   [[group]]
//   name            = "protocol"
//   kind            = "ba"                      # "run" (default): the keys above
//   problems        = ["../datasets/bal/ladybug-problem-49-7776-pre.txt.bz2"]  # BAL files
//                                               # (relative to the sweep file)
//   solvers         = ["ns-f32", "ceres-sparse"] # or "all" (the seven of `marglab ba`)
//   seeds           = [38401]                   # perturbation seeds, default [38401]
//   iterations      = 50                        # optional, as `marglab ba` (default 20)
//   huber_px        = 1.0                       # optional (default 0: no robust loss)
//   perturb_sigma   = 0.01                      # optional (default 0: no perturbation)
//   normalize_scale = 100.0                     # optional (default 0: no normalization)
//   threads         = 1                         # optional
//   timeout_s       = 0                         # optional
// Run ids: <group>__<problem name>__<solver>__s<seed> (problem name: the file name without .txt
// and .bz2). Each run is a typed BaRunSpec (core/ba/ba_run_spec.h), validated at plan time — every
// setting in its range at its key's line, every problem file read and parsed once (a malformed
// file names its line), a solver name known — and its child runs `marglab ba --spec
// runs/<id>.spec.toml`.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/ba/ba_run_spec.h"
#include "core/frontend/track_source.h"

namespace marglab::experiment {

struct PlannedRun {
  std::string id;       // unique within the sweep, safe as a file name
  std::string group;    // group name
  std::string dataset;  // as `marglab run --dataset` takes it (folders resolved to absolute)
  std::string variant;  // canonical variant name, e.g. "ns-qr-sqrt-f32"
  std::uint64_t seed = 1;
  int frames = 0;                        // 0: whole sequence
  double timeout_s = 0;                  // 0: none
  std::string override_name;             // "" for the unnamed override
  std::optional<FrontendKind> frontend;  // nullopt: not passed (the run's default, auto)
  std::vector<std::string> extra_args;   // group args, then override args
  std::string config_toml;               // merged config overrides (TOML text), "" when none
  // The spec its child runs (`marglab run --spec runs/<id>.spec.toml`, core/pipeline/run_spec.h),
  // as the checker built and validated it; "" without a checker: the child gets runArguments.
  std::string spec_toml;
  int line = 0;  // line of the group in the sweep file (for messages)
  // A `marglab ba` run (group kind "ba"): its spec, output runs/<id>.h5. Then dataset is its
  // problem file (absolute), variant its solver, seed its perturbation seed; frames, override,
  // frontend, extra_args and config_toml are unused.
  std::optional<BaRunSpec> ba;
};

struct SweepPlan {
  std::string name;
  std::string description;
  std::string source_file;  // the sweep file as given
  std::vector<PlannedRun> runs;
};

// Checks extra `marglab run` options; returns "" when fine, else what is wrong. The CLI passes a
// checker that parses them with the real `run` verb; the library default accepts everything.
using RunArgsChecker = std::function<std::string(const std::vector<std::string>& args)>;

// Checks one planned run as a whole (its dataset with its options); returns "" when fine, else
// what is wrong, and sets run->spec_toml. The CLI's validates the run's spec as `marglab run` does.
using RunChecker = std::function<std::string(PlannedRun* run)>;

struct ParseOptions {
  RunArgsChecker check_run_args;
  RunChecker check_run;
  // The sequences a dataset name may be (default: listSequences()).
  std::vector<std::string> known_sequences;
  bool known_sequences_given = false;
};

// The most runs a sweep plans (a larger one is refused at the group that exceeds it): its index is
// rewritten as runs end, and a million-row index is no way to work.
inline constexpr int kMaxSweepRuns = 100000;

// Reads and validates a sweep file; throws InputError(file, line, what).
SweepPlan loadSweepFile(const std::string& path, const ParseOptions& options = {});
// The same from text (`name` is used in messages; relative folders resolve against base_dir).
SweepPlan parseSweep(const std::string& text, const std::string& name, const std::string& base_dir,
                     const ParseOptions& options = {});

// The variants a `variants` entry stands for (a set name or one variant); throws UsageError.
std::vector<std::string> expandVariantEntry(const std::string& entry);

// "kitti/10" → "kitti-10"; anything outside [A-Za-z0-9_.-] becomes '-'.
std::string slug(const std::string& text);

// The track file of an images run, relative to the sweep folder: "tracks/<dataset slug>.h5".
std::string sweepTrackFile(const PlannedRun& run);

// The `marglab run` arguments of a planned run (without the program name), with the results file
// and, when config_toml is non-empty, the config file it was written to; of a ba run, the
// `marglab ba` arguments with every setting.
std::vector<std::string> runArguments(const PlannedRun& run, const std::string& results_path,
                                      const std::string& config_path);

// The spec file of a run, relative to the sweep folder: "runs/<id>.spec.toml".
std::string runSpecFile(const PlannedRun& run);

// What the child of a run is given: `run --spec runs/<id>.spec.toml` (a ba run: `ba --spec ...`)
// where the plan holds its spec, else runArguments(run, results_path, config_path).
std::vector<std::string> childArguments(const PlannedRun& run, const std::string& results_path,
                                        const std::string& config_path);

}  // namespace marglab::experiment
