#pragma once
// The options of `marglab run` and how they become the one RunSpec (core/pipeline/run_spec.h):
// `marglab run` parses its command line with them, and `marglab sweep` parses every planned run's
// arguments with the same options at plan time, so that both build the same spec and validate it
// with the same runProblems.
//
// Precedence: defaults < --config FILE < --set KEY=VALUE (in order) < the config-key options
// (--threads, --marg-strategy, ...: aliases of --set, each recorded as the origin of its key).
// --spec FILE gives the whole run instead (only -o may be given beside it).

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "core/pipeline/run_spec.h"

namespace marglab::cli {

struct RunArgs {
  RunSpec spec;  // the options bound directly (dataset, seed, frames, output, ...)
  std::string spec_file;
  std::string variant;
  std::string mode = "auto";
  std::string imu = "synthetic";
  std::string frontend = "auto";
  std::string config_file;
  std::vector<std::string> sets;
  // The config-key options given, in the order of kConfigKeyOptions (run_args.cpp); "" if not.
  std::vector<std::string> config_key_values;
  bool no_diagnostics = false;
  bool output_given = false;  // -o, even empty (then an error of its own)
};

// Registers the options of `marglab run` on `app`.
void addRunOptions(CLI::App& app, RunArgs& args);

// The spec of parsed options: from --spec FILE, or the options on the defaults and --config.
// Throws UsageError (a missing --dataset, a bad --set) and InputError (a bad config or spec file).
RunSpec runSpecFrom(const RunArgs& args);

// What is wrong with a list of `marglab run` options ("" when they parse): a sweep group's `args`.
std::string runOptionsProblem(const std::vector<std::string>& arguments);

// The spec of a `marglab run` argument list (without "run"), with config_text (a sweep's merged
// config, named config_name in messages) in place of a --config file. For the sweep's plan.
// Throws what runSpecFrom throws, and UsageError with CLI11's message for a bad option.
RunSpec parseRunArguments(const std::vector<std::string>& arguments, const std::string& config_text,
                          const std::string& config_name);

}  // namespace marglab::cli
