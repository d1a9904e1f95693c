// `marglab run`: one variant on one sequence → one HDF5 results file (+ TUM trajectory).
// The options and their precedence: tools/run_args.h.

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>

#include "core/bench/isa_choice.h"
#include "core/common/error.h"
#include "core/common/interrupt.h"
#include "core/data/plausibility.h"
#include "core/data/sequence.h"
#include "core/frontend/image_folder.h"
#include "core/linalg/isa.h"
#include "core/pipeline/run.h"
#include "tools/command.h"
#include "tools/option_checks.h"
#include "tools/output_checks.h"
#include "tools/run_args.h"

namespace marglab {
namespace {

// The output paths, checked before any work: writable, and none of them an input of the run.
void checkOutputs(const RunSpec& spec, const cli::RunArgs& args) {
  cli::checkOutputFile(spec.output, "-o");
  cli::checkOutputFile(tumPathFor(spec.output), "the TUM trajectory beside -o");
  std::vector<std::string> outputs{spec.output, tumPathFor(spec.output)};
  for (const int frame : spec.dump_windows) {
    outputs.push_back((std::filesystem::path(spec.dump_dir) /
                       windowFileName(spec.dataset, spec.variant.name(), frame))
                          .string());
  }
  cli::CommandInputs inputs{{args.config_file, args.spec_file, spec.tracks_file}, {}};
  cli::addInputs(&inputs, cli::datasetInputs(spec.dataset));
  cli::refuseOverwritingInputs(outputs, inputs);
}

void printOutcome(const RunSpec& spec, const RunOutcome& outcome);

// The progress line on a terminal; polls for SIGINT/SIGTERM once frames are being processed (the
// loop stops after the current frame and unwinds, removing the results file's temporary; before,
// the handler removes it, interrupt.h).
RunProgress progressLine(std::optional<InterruptPolling>* polling) {
  const auto start = std::chrono::steady_clock::now();
  const bool terminal = cli::stderrIsTerminal();
  return [start, terminal, polling](int done, int total) {
    if (!*polling) polling->emplace();
    throwIfInterrupted();
    if (!terminal) return;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double rate = done / std::max(elapsed, 1e-9);
    fmt::print(stderr, "\r  frame {:>6}/{:<6} {:7.1f} frames/s  ETA {:6.1f} s ", done, total, rate,
               (total - done) / std::max(rate, 1e-9));
  };
}

// spec → checks of the outputs → prepareRun (load, resolve, validate: every problem before any
// work) → run.
int runRun(const cli::RunArgs& args) {
  const RunSpec spec = cli::runSpecFrom(args);
  cli::checkDatasetArgument(spec.dataset);
  resolveIsa(spec.isa);  // the name, before any work
  checkOutputs(spec, args);
  PreparedRun prepared = prepareRun(spec);
  activateIsa(spec.isa);  // `auto` measures once per machine and build, after the checks
  if (const std::string note = pathLengthNote(prepared.inputs.dataset.sequence); !note.empty()) {
    fmt::print(stderr, "marglab run: note: {}: {}\n", prepared.inputs.dataset.sequence.gt_file,
               note);
  }
  if (const auto& images = prepared.inputs.dataset.images; images) {
    if (const std::string note = unpairedFramesNote(*images); !note.empty()) {
      fmt::print(stderr, "marglab run: note: {}\n", note);
    }
  }
  if (!spec.dump_windows.empty()) std::filesystem::create_directories(spec.dump_dir);
  const bool terminal = cli::stderrIsTerminal();
  std::optional<InterruptPolling> polling;
  RunOutcome outcome;
  try {
    outcome = runPrepared(std::move(prepared), progressLine(&polling));
    throwIfInterrupted();  // a signal after the last frame: the files are complete
  } catch (const Interrupted& e) {
    fmt::print(stderr, "{}marglab: {}: stopped, no results file written\n", terminal ? "\n" : "",
               e.what());
    return e.exitCode();
  }
  if (terminal) fmt::print(stderr, "\n");
  printOutcome(spec, outcome);
  return outcome.status == RunStatus::kOk ? 0 : 1;
}

void printOutcome(const RunSpec& spec, const RunOutcome& outcome) {
  const SummaryValues& s = outcome.summary;
  fmt::print("marglab run {} {} {} (seed {}{})\n", spec.dataset, outcome.vio ? "VIO" : "VO",
             spec.variant.name(), spec.seed,
             outcome.vio ? std::string(", IMU ") + nameOf(kImuSourceNames, spec.imu) : "");
  fmt::print("  status            {}\n",
             outcome.status == RunStatus::kOk
                 ? "ok"
                 : fmt::format("FAILED at frame {} ({}): {}", outcome.failure_frame,
                               outcome.failure_kind, outcome.failure_reason));
  fmt::print("  frames            {} ({:.1f} s of data, {:.0f} features/frame)\n", s.n_frames,
             s.duration_s, outcome.mean_features_per_frame);
  fmt::print("  front-end         {}\n", outcome.frontend_summary);
  if (s.n_ate_pairs >= 3) {
    fmt::print("  ATE RMSE          {:.4f} m ({} pairs, SE(3)-aligned)\n", s.ate_rmse,
               s.n_ate_pairs);
  } else if (s.n_ate_pairs > 0) {
    // An SE(3) alignment of 1 or 2 positions fits them exactly: the 0 it gives says nothing.
    fmt::print("  ATE RMSE          unavailable ({} pair(s); the SE(3) alignment needs 3)\n",
               s.n_ate_pairs);
  } else {
    fmt::print("  ATE RMSE          unavailable (no ground truth for these frames)\n");
  }
  fmt::print("  time opt / marg   {:.3f} s / {:.3f} s\n", s.t_opt_total_s, s.t_marg_total_s);
  fmt::print("  real-time factor  {:.1f}x\n", s.realtime_factor);
  if (outcome.marg_strategy == MargStrategy::kDiscard) {
    fmt::print("  marginalizations  {}\n", s.n_marg);
  } else {
    // The gauge diagnostics (/marg) analyse priors over frame states: discard only.
    fmt::print("  keyframe events   {} ({}; /sparsify)\n", outcome.n_keyframe_events,
               toString(outcome.marg_strategy));
  }
  fmt::print("  results           {}\n  trajectory (TUM)  {}\n", spec.output, outcome.tum_path);
}

const bool kRegistered = cli::registerCommand(
    {"run", "Run one estimator variant on one sequence and write an HDF5 results file", 10,
     [](CLI::App& sub) -> cli::CommandRun {
       auto args = std::make_shared<cli::RunArgs>();
       cli::addRunOptions(sub, *args);
       return [args] { return runRun(*args); };
     }});

}  // namespace
}  // namespace marglab
