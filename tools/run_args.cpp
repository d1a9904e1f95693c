#include "tools/run_args.h"

#include <fmt/core.h>

#include <algorithm>
#include <functional>
#include <iterator>
#include <map>

#include "core/common/error.h"
#include "tools/option_checks.h"

namespace marglab::cli {
namespace {

// The options that set one config key each: aliases of --set KEY=VALUE, checked against the key's
// range or names while parsing. A new one is one line here; any key is reachable through --set.
struct ConfigKeyOption {
  const char* option;
  const char* key;
  const char* help;
};
constexpr ConfigKeyOption kConfigKeyOptions[] = {
    {"--qr-threshold-mode", "marginalization.qr_threshold_mode",
     "Flat-QR rank threshold: absolute (default) or relative"},
    {"--qr-threshold", "marginalization.qr_threshold",
     "Flat-QR rank threshold value, >= 0, below 1 when relative (default -1: sqrt(eps) of the "
     "precision)"},
    {"--threads", "lm.threads",
     "Threads of the LM loop over landmark blocks, 1 to 256 (default 1 = lm.threads: timings "
     "comparable between variants)"},
    {"--marg-strategy", "marginalization.strategy",
     "Keyframe marginalization (VIO): discard (default, OKVIS/VINS-Mono), dense (landmarks stay, "
     "dense prior) or nfr (dense prior sparsified by nonlinear factor recovery)"},
    {"--store-prior-every", "diagnostics.store_prior_every",
     "Store the full prior of every k-th marginalization (0: none; default 25) for `eigdump "
     "--matrix`"},
};
constexpr std::size_t kNumConfigKeyOptions = std::size(kConfigKeyOptions);

template <typename E, std::size_t N>
CLI::Option* addChoice(CLI::App& app, const std::string& name, std::string* value,
                       const EnumNames<E, N>& names, const std::string& help) {
  return app.add_option(name, *value, help)
      ->check(CLI::IsMember(namesOf(names)))
      ->capture_default_str();
}

// What runs: the sequence, the variant, where the tracks come from, how many frames.
void addRunSubject(CLI::App& app, RunArgs& args) {
  RunSpec& spec = args.spec;
  app.add_option("--dataset", spec.dataset,
                 "Sequence name (see `marglab datasets list`, e.g. kitti/10) or a folder in "
                 "EuRoC/TUM-VI (mav0/) or KITTI layout");
  app.add_option("--variant", args.variant, variantSyntax());
  app.add_option("--isa", spec.isa,
                 "Instruction set of the kernels (auto: the fastest on this machine, measured once "
                 "per CPU and build and cached; docs/design.md §ISA dispatch); recorded in the "
                 "results file's isa and isa_choice attributes")
      ->check(CLI::IsMember({"auto", "sse2", "avx2", "avx512"}))
      ->capture_default_str();
  addChoice(app, "--mode", &args.mode, kRunModeNames,
            "vo (stereo), vio (stereo + IMU) or auto: vio where the dataset has an IMU (EuRoC, "
            "TUM-VI), vo on KITTI");
  addChoice(app, "--imu", &args.imu, kImuSourceNames,
            "VIO: synthetic IMU from the trajectory, or the sequence's real recording");
  addChoice(app, "--frontend", &args.frontend, kFrontendKindNames,
            "Feature tracks: images (the optical-flow front-end on the folder's images), "
            "simulated (along the ground truth) or auto: images where the folder has them");
  app.add_option("--tracks", spec.tracks_file,
                 "Run on this track file (HDF5 or text, datasets/README.md) instead of a "
                 "front-end; --dataset supplies calibration, ground truth and IMU")
      ->check(existingPath("--tracks", PathKind::kFile));
  app.add_flag("--tracks-any-sequence", spec.tracks_any_sequence,
               "Run on a --tracks file recorded for another sequence or at other timestamps "
               "(refused by default)");
  app.add_option("--frames", spec.max_frames, "Process only the first N frames (0: all)")
      ->capture_default_str()
      ->check(nonNegativeInt("the number of frames (0: all)"));
  app.add_option("--seed", spec.seed,
                 "Seed of the simulated world, tracks and noise, in [0, 2^64 - 1]")
      ->capture_default_str()
      ->check(seedRange());
}

// The config: --config, --set and the config-key options.
void addRunConfig(CLI::App& app, RunArgs& args) {
  app.add_option("--config", args.config_file, "Estimator config (TOML), see README")
      ->check(existingPath("--config", PathKind::kFile));
  app.add_option("--set", args.sets,
                 "Set one config key, section.key=value (repeatable), e.g. --set "
                 "lm.max_iterations=3; keys and ranges: docs/design.md §9")
      ->allow_extra_args(false);
  args.config_key_values.assign(kNumConfigKeyOptions, "");
  for (std::size_t k = 0; k < kNumConfigKeyOptions; ++k) {
    const ConfigKeyOption& o = kConfigKeyOptions[k];
    app.add_option(o.option, args.config_key_values[k], fmt::format("{} (= {})", o.help, o.key))
        ->check(configKeyRange(o.key));
  }
  app.add_flag("--no-diagnostics", args.no_diagnostics,
               "Skip the shadow prior and its eigenvalues (= diagnostics.enabled=false)");
}

// Where it writes, what it captures, and --spec.
void addRunOutputs(CLI::App& app, RunArgs& args) {
  RunSpec& spec = args.spec;
  app.add_option("-o,--output", spec.output, "Results file (HDF5)")
      ->each([&args](const std::string&) { args.output_given = true; });
  app.add_option("--dump-windows", spec.dump_windows,
                 "Capture the windows of these frames (comma-separated 0-based indices) before "
                 "their optimization, with the step taken, for `marglab bench` and the tests")
      ->delimiter(',')
      ->check(nonNegativeInt("a frame index"));
  app.add_option("--dump-dir", spec.dump_dir, "Folder of the captured windows")
      ->capture_default_str();
  app.add_option("--inject-nan-frame", spec.inject_nan_frame,
                 "Testing: put a NaN into a measurement of this frame")
      ->group("");
  app.add_option("--spec", args.spec_file,
                 "Run a spec file (a sweep's runs/<id>.spec.toml, or the results file's run_spec "
                 "attribute saved as a file); only -o may be given beside it")
      ->check(existingPath("--spec", PathKind::kFile));
}

// --spec gives the whole run: any other option beside -o is refused.
void checkSpecAlone(const CLI::App& app) {
  for (const CLI::Option* option : app.get_options()) {
    const std::string name = option->get_name();
    if (option->count() == 0 || name == "--spec" || name == "--output" || name == "--help") {
      continue;
    }
    // Thrown while parsing: a CLI11 error, reported like any other bad option (exit 2).
    throw CLI::ValidationError(
        "--spec",
        fmt::format("FILE gives the whole run: {} cannot be given beside it (only -o)", name));
  }
}

template <typename E, std::size_t N>
E parsedChoice(const EnumNames<E, N>& names, const std::string& text) {
  E value{};
  parseName(names, text, &value);  // CLI11 has checked the name
  return value;
}

// The config's command-line layers over the spec's config: --set in order, then the aliases.
void applyConfigOptions(const RunArgs& args, RunSpec* spec) {
  for (const std::string& assignment : args.sets) {
    spec->config.set(assignment, "--set");
    spec->overrides.push_back(assignment);
  }
  for (std::size_t k = 0; k < kNumConfigKeyOptions; ++k) {
    const std::string& value = args.config_key_values[k];
    if (value.empty()) continue;
    const ConfigKeyOption& o = kConfigKeyOptions[k];
    spec->config.set(fmt::format("{}={}", o.key, value), o.option);
    spec->overrides.push_back(fmt::format("{}={}", o.key, value));
  }
  if (args.no_diagnostics) {
    spec->config.set("diagnostics.enabled=false", "--no-diagnostics");
    spec->overrides.emplace_back("diagnostics.enabled=false");
  }
}

// The spec of the options (not --spec), its config file loaded by load_config.
RunSpec specOfOptions(const RunArgs& args, const std::function<void(RunConfig*)>& load_config) {
  if (args.spec.dataset.empty()) throw UsageError("--dataset is required (or --spec FILE)");
  if (args.variant.empty()) throw UsageError("--variant is required (or --spec FILE)");
  if (!args.output_given) throw UsageError("-o is required: the results file to write");
  RunSpec spec = args.spec;
  spec.variant = Variant::parse(args.variant);
  spec.mode = parsedChoice(kRunModeNames, args.mode);
  spec.imu = parsedChoice(kImuSourceNames, args.imu);
  spec.frontend = parsedChoice(kFrontendKindNames, args.frontend);
  load_config(&spec.config);
  applyConfigOptions(args, &spec);
  return spec;
}

}  // namespace

void addRunOptions(CLI::App& app, RunArgs& args) {
  addRunSubject(app, args);
  addRunConfig(app, args);
  addRunOutputs(app, args);
  app.final_callback([&app, &args] {
    if (!args.spec_file.empty()) checkSpecAlone(app);
  });
}

RunSpec runSpecFrom(const RunArgs& args) {
  if (!args.spec_file.empty()) {
    RunSpec spec = RunSpec::fromTomlFile(args.spec_file);
    if (args.output_given) spec.output = args.spec.output;
    return spec;
  }
  return specOfOptions(args, [&args](RunConfig* config) {
    if (!args.config_file.empty()) config->loadToml(args.config_file);
  });
}

namespace {

// `arguments` (without "run") parsed into args with the options of `marglab run` on `app`. Throws
// UsageError with CLI11's message, InputError for a missing input path.
void parseArguments(const std::vector<std::string>& arguments, CLI::App* app, RunArgs* args) {
  addRunOptions(*app, *args);
  std::vector<std::string> reversed(arguments.rbegin(), arguments.rend());  // CLI11's order
  try {
    app->parse(reversed);
  } catch (const CLI::Success&) {  // --help: CLI11's what() is "This should be caught in your main"
    throw UsageError("--help prints the options and runs nothing: not an option of a run");
  } catch (const CLI::ParseError& e) {
    throw UsageError(e.what());
  }
}

}  // namespace

std::string runOptionsProblem(const std::vector<std::string>& arguments) {
  CLI::App app{"run"};
  RunArgs args;
  try {
    parseArguments(arguments, &app, &args);
  } catch (const UsageError& e) {
    return e.what();
  } catch (const InputError& e) {
    return e.what();
  }
  return {};
}

RunSpec parseRunArguments(const std::vector<std::string>& arguments, const std::string& config_text,
                          const std::string& config_name) {
  CLI::App app{"run"};
  RunArgs args;
  parseArguments(arguments, &app, &args);
  if (!args.spec_file.empty()) return runSpecFrom(args);
  return specOfOptions(args, [&](RunConfig* config) {
    if (!config_text.empty()) config->loadTomlString(config_text, config_name);
    if (!args.config_file.empty()) config->loadToml(args.config_file);
  });
}

}  // namespace marglab::cli
