// `marglab run`: one variant on one sequence → one HDF5 results file (+ TUM trajectory).
// Precedence of settings: defaults < --config FILE < command-line options.

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>

#include "core/common/error.h"
#include "core/common/interrupt.h"
#include "core/data/plausibility.h"
#include "core/data/sequence.h"
#include "core/frontend/image_folder.h"
#include "core/linalg/isa.h"
#include "core/pipeline/run.h"
#include "core/sim/track_io.h"
#include "tools/command.h"
#include "tools/option_checks.h"
#include "tools/output_checks.h"

namespace marglab {
namespace {

struct RunArgs {
  std::string dataset;
  std::string variant;
  std::string mode = "auto";
  std::string imu = "synthetic";
  std::string frontend = "auto";
  std::string tracks;
  int frames = 0;
  std::uint64_t seed = 1;
  std::string config_file;
  std::string output;
  std::string qr_threshold_mode;
  std::optional<double> qr_threshold;
  bool no_diagnostics = false;
  std::optional<int> store_prior_every;
  std::optional<int> threads;
  std::string marg_strategy;
  int inject_nan_frame = -1;
  std::vector<int> dump_windows;
  std::string dump_dir = "windows";
  std::string isa = "auto";
  bool tracks_any_sequence = false;
};

// The input files, checked before any work (issue #32: a run must not track images or estimate for
// minutes and then fail on its input): the track file against the dataset (its sequence and
// timestamps), a real IMU against the camera frames, the output path. A static or short recording
// is run, with a note. The options themselves are validated once, by runSequence
// (resolveRunOptions).
void checkInputsBeforeRunning(const RunArgs& args) {
  cli::checkOutputFile(args.output, "-o");
  cli::checkOutputFile(tumPathFor(args.output), "the TUM trajectory beside -o");
  const Sequence sequence = loadImageSequence(args.dataset).sequence;
  if (!args.tracks.empty() && !args.tracks_any_sequence) {
    checkTracksBelongTo(readTrackFile(args.tracks), args.tracks, sequence);
  }
  if (args.imu == "real") checkImuCoverage(sequence);
  if (const std::string note = pathLengthNote(sequence); !note.empty()) {
    fmt::print(stderr, "marglab run: note: {}: {}\n", sequence.gt_file, note);
  }
}

// The results file, its TUM trajectory and the captured windows against the files and folders
// the run reads.
void refuseOverwritingInputs(const RunArgs& args) {
  std::vector<std::string> outputs{args.output, tumPathFor(args.output)};
  for (const int frame : args.dump_windows) {
    outputs.push_back((std::filesystem::path(args.dump_dir) /
                       windowFileName(args.dataset, Variant::parse(args.variant).name(), frame))
                          .string());
  }
  cli::refuseOverwritingInputs(
      outputs, {{args.config_file, args.tracks}, cli::datasetInputFolders(args.dataset)});
}

// The config: defaults < --config < options; each option records itself as the origin of its
// key, so that the validation names the option (usage error) or the file and line (input error).
EstimatorConfig configFrom(const RunArgs& args) {
  EstimatorConfig config;
  if (!args.config_file.empty()) config.loadToml(args.config_file);
  if (!args.qr_threshold_mode.empty()) {
    if (!parseRankThresholdMode(args.qr_threshold_mode, &config.qr_threshold_mode)) {
      throw UsageError("--qr-threshold-mode must be absolute or relative");
    }
    config.setOrigin("marginalization.qr_threshold_mode", "--qr-threshold-mode");
  }
  if (args.qr_threshold) {
    config.qr_threshold = *args.qr_threshold;
    config.setOrigin("marginalization.qr_threshold", "--qr-threshold");
  }
  if (args.no_diagnostics) {
    config.diagnostics = false;
    config.setOrigin("diagnostics.enabled", "--no-diagnostics");
  }
  if (args.store_prior_every) {
    config.store_prior_every = *args.store_prior_every;
    config.setOrigin("diagnostics.store_prior_every", "--store-prior-every");
  }
  if (args.threads) {
    config.lm_threads = *args.threads;
    config.setOrigin("lm.threads", "--threads");
  }
  if (!args.marg_strategy.empty()) {
    if (!parseMargStrategy(args.marg_strategy, &config.marg_strategy)) {
      throw UsageError("--marg-strategy must be discard, dense or nfr");
    }
    config.setOrigin("marginalization.strategy", "--marg-strategy");
  }
  return config;
}

RunOptions optionsFrom(const RunArgs& args) {
  RunOptions options;
  options.dataset = args.dataset;
  options.variant = Variant::parse(args.variant);
  options.mode = args.mode == "vo"    ? RunMode::kVo
                 : args.mode == "vio" ? RunMode::kVio
                                      : RunMode::kAuto;
  options.imu = args.imu == "real" ? ImuSource::kReal : ImuSource::kSynthetic;
  if (!parseFrontendKind(args.frontend, &options.frontend)) {
    throw UsageError("--frontend must be auto, images or simulated");
  }
  options.tracks_file = args.tracks;
  options.max_frames = args.frames;
  options.seed = args.seed;
  options.output = args.output;
  options.inject_nan_frame = args.inject_nan_frame;
  options.dump_windows = args.dump_windows;
  options.dump_dir = args.dump_dir;
  options.config = configFrom(args);
  return options;
}

void printOutcome(const RunArgs& args, const RunOptions& options, const RunOutcome& outcome);

int runRun(const RunArgs& args) {
  cli::checkDatasetArgument(args.dataset);
  setActiveIsa(resolveIsa(args.isa));
  RunOptions options = optionsFrom(args);
  refuseOverwritingInputs(args);
  checkInputsBeforeRunning(args);
  if (!options.dump_windows.empty()) std::filesystem::create_directories(options.dump_dir);

  const auto start = std::chrono::steady_clock::now();
  const bool terminal = cli::stderrIsTerminal();
  // SIGINT/SIGTERM: once frames are being processed the loop stops after the current frame and
  // unwinds (removing the results file's temporary); before, the handler removes it (interrupt.h).
  std::optional<InterruptPolling> polling;
  options.progress = [start, terminal, &polling](int done, int total) {
    if (!polling) polling.emplace();
    throwIfInterrupted();
    if (!terminal) return;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double rate = done / std::max(elapsed, 1e-9);
    fmt::print(stderr, "\r  frame {:>6}/{:<6} {:7.1f} frames/s  ETA {:6.1f} s ", done, total, rate,
               (total - done) / std::max(rate, 1e-9));
  };
  RunOutcome outcome;
  try {
    outcome = runSequence(options);
    throwIfInterrupted();  // a signal after the last frame: the files are complete
  } catch (const Interrupted& e) {
    fmt::print(stderr, "{}marglab: {}: stopped, no results file written\n", terminal ? "\n" : "",
               e.what());
    return e.exitCode();
  } catch (const InputError& e) {
    // The trajectory is written after the results file: both or neither.
    if (e.file() != tumPathFor(args.output)) throw;
    std::error_code ec;
    std::filesystem::remove(args.output, ec);
    throw InputError(e.file(), e.line(),
                     e.detail() + " (the results file " + args.output +
                         " was removed with it: a run leaves both files or neither)");
  }
  if (terminal) fmt::print(stderr, "\n");

  printOutcome(args, options, outcome);
  return outcome.status == RunStatus::kOk ? 0 : 1;
}

void printOutcome(const RunArgs& args, const RunOptions& options, const RunOutcome& outcome) {
  const SummaryValues& s = outcome.summary;
  fmt::print("marglab run {} {} {} (seed {}{})\n", args.dataset, outcome.vio ? "VIO" : "VO",
             options.variant.name(), args.seed, outcome.vio ? ", IMU " + args.imu : "");
  fmt::print(
      "  status            {}\n",
      outcome.status == RunStatus::kOk
          ? "ok"
          : fmt::format("FAILED at frame {} ({}): {}", outcome.failure_frame, outcome.failure_kind,
                        outcome.failure_reason));
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
  fmt::print("  results           {}\n  trajectory (TUM)  {}\n", args.output, outcome.tum_path);
}

// What runs: the sequence, the variant, where the tracks come from, how many frames.
void addRunSubject(CLI::App& sub, RunArgs& args) {
  sub.add_option("--dataset", args.dataset,
                 "Sequence name (see `marglab datasets list`, e.g. kitti/10) or a folder in "
                 "EuRoC/TUM-VI (mav0/) or KITTI layout")
      ->required();
  sub.add_option("--variant", args.variant,
                 "opt-marg-storage-precision, e.g. ns-qr-sqrt-f32 (opt ns|sc, marg qr|sc, "
                 "storage sqrt|sq|sqp|sqj|sqrtp, precision f32|f64|mixed)")
      ->required();
  sub.add_option("--isa", args.isa,
                 "Instruction set of the kernels (auto: the widest this CPU has); recorded in "
                 "the results file's isa attribute")
      ->check(CLI::IsMember({"auto", "sse2", "avx2", "avx512"}))
      ->capture_default_str();
  sub.add_option("--mode", args.mode,
                 "vo (stereo), vio (stereo + IMU) or auto: vio where the dataset has an IMU "
                 "(EuRoC, TUM-VI), vo on KITTI")
      ->check(CLI::IsMember({"auto", "vo", "vio"}))
      ->capture_default_str();
  sub.add_option("--imu", args.imu,
                 "VIO: synthetic IMU from the trajectory, or the sequence's real recording")
      ->check(CLI::IsMember({"synthetic", "real"}))
      ->capture_default_str();
  sub.add_option("--frontend", args.frontend,
                 "Feature tracks: images (the optical-flow front-end on the folder's "
                 "images), simulated (along the ground truth) or auto: images where the "
                 "folder has them")
      ->check(CLI::IsMember({"auto", "images", "simulated"}))
      ->capture_default_str();
  sub.add_option("--tracks", args.tracks,
                 "Run on this track file (HDF5 or text, datasets/README.md) instead of a "
                 "front-end; --dataset supplies calibration, ground truth and IMU")
      ->check(cli::existingPath("--tracks", cli::PathKind::kFile));
  sub.add_flag("--tracks-any-sequence", args.tracks_any_sequence,
               "Run on a --tracks file recorded for another sequence or at other timestamps "
               "(refused by default)");
  sub.add_option("--frames", args.frames, "Process only the first N frames (0: all)")
      ->capture_default_str()
      ->check(cli::nonNegativeInt("the number of frames (0: all)"));
  sub.add_option("--seed", args.seed,
                 "Seed of the simulated world, tracks and noise, in [0, 2^64 - 1]")
      ->capture_default_str()
      ->check(cli::seedRange());
}

// How it runs and where it writes: config, output, the config-key options, captures.
void addRunSettings(CLI::App& sub, RunArgs& args) {
  sub.add_option("--config", args.config_file, "Estimator config (TOML), see README")
      ->check(cli::existingPath("--config", cli::PathKind::kFile));
  sub.add_option("-o,--output", args.output, "Results file (HDF5)")->required();
  sub.add_option("--qr-threshold-mode", args.qr_threshold_mode,
                 "Flat-QR rank threshold: absolute (default) or relative")
      ->check(CLI::IsMember({"absolute", "relative"}));
  sub.add_option("--qr-threshold", args.qr_threshold,
                 "Flat-QR rank threshold value, >= 0, below 1 when relative (default -1: "
                 "sqrt(eps) of the precision)")
      ->check(cli::configKeyRange("marginalization.qr_threshold"));
  sub.add_option("--threads", args.threads,
                 "Threads of the LM loop over landmark blocks, 1 to 256 (default 1 = "
                 "lm.threads: timings comparable between variants)")
      ->check(cli::configKeyRange("lm.threads"));
  sub.add_option("--marg-strategy", args.marg_strategy,
                 "Keyframe marginalization (VIO): discard (default, OKVIS/VINS-Mono), dense "
                 "(landmarks stay, dense prior) or nfr (dense prior sparsified by nonlinear "
                 "factor recovery) = marginalization.strategy")
      ->check(CLI::IsMember({"discard", "dense", "nfr"}));
  sub.add_flag("--no-diagnostics", args.no_diagnostics,
               "Skip the shadow prior and its eigenvalues");
  sub.add_option("--store-prior-every", args.store_prior_every,
                 "Store the full prior of every k-th marginalization (0: none; default 25) "
                 "for `eigdump --matrix`")
      ->check(cli::configKeyRange("diagnostics.store_prior_every"));
  sub.add_option("--dump-windows", args.dump_windows,
                 "Capture the windows of these frames (comma-separated 0-based indices) before "
                 "their optimization, with the step taken, for `marglab bench` and the tests")
      ->delimiter(',')
      ->check(cli::nonNegativeInt("a frame index"));
  sub.add_option("--dump-dir", args.dump_dir, "Folder of the captured windows")
      ->capture_default_str();
  sub.add_option("--inject-nan-frame", args.inject_nan_frame,
                 "Testing: put a NaN into a measurement of this frame")
      ->group("");
}

const bool kRegistered = cli::registerCommand(
    {"run", "Run one estimator variant on one sequence and write an HDF5 results file", 10,
     [](CLI::App& sub) -> cli::CommandRun {
       auto args = std::make_shared<RunArgs>();
       addRunSubject(sub, *args);
       addRunSettings(sub, *args);
       return [args] { return runRun(*args); };
     }});

}  // namespace
}  // namespace marglab
