// `marglab datasets <sub-verb>`: the real datasets shipped in datasets/ (or a user's folder).
//
//   marglab datasets list                   table of the shipped sequences
//   marglab datasets check [--all | SEQ...]  load + validate as `run` does (the camera models and
//                                           every image too), one line per sequence; exit 1 on
//                                           error
//   marglab datasets simulate --dataset SEQ [--seed S] [--frames N] [--no-noise]
//                             [--profile ideal|realistic|realistic-motion] -o FILE
//                                           simulated stereo tracks along the GT spline -> track
//                                           file (.h5 / .hdf5: HDF5, else text) + statistics
//   marglab datasets track --dataset PATH [--frames N] [--passes P] -o FILE
//                                           the image front-end on the folder's stereo images ->
//                                           track file, statistics and front-end speed
//   marglab datasets render --dataset SEQ [--frames N] [--start S] [--seed S] -o FOLDER
//                                           stereo images rendered from the simulated world
//                                           along SEQ's trajectory through its real camera
//                                           model -> a dataset folder in SEQ's original layout
//                                           (core/frontend/rendered_folder.h)
//   marglab datasets stereo-bias --dataset DIR [--frames A:B] [--config F] [--poses TUM]
//                                -o BIAS.toml
//                                           a KITTI folder's disparities against motion stereo
//                                           (ground-truth poses) -> report + config fragment
//                                           [calibration] right_cx_shift_px for `run --config`
//                                           (core/frontend/stereo_bias.h)
//
// Each sub-verb is one entry of kSubVerbs below: a name, a description and a setup function that
// adds the sub-verb's options and returns its run function (as for top-level verbs).

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/common/interrupt.h"
#include "core/data/parsers.h"
#include "core/data/sequence.h"
#include "core/frontend/image_check.h"
#include "core/frontend/image_folder.h"
#include "core/frontend/rendered_folder.h"
#include "core/frontend/stereo_bias.h"
#include "core/frontend/track_source.h"
#include "core/imu/noise_profile.h"
#include "core/pipeline/run_config.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/imu_hold.h"
#include "core/sim/imu_synth.h"
#include "core/sim/sim_profile.h"
#include "core/sim/track_io.h"
#include "core/sim/trajectory_spline.h"
#include "tools/command.h"
#include "tools/option_checks.h"
#include "tools/output_checks.h"

namespace marglab::cli {
namespace {

std::string calibrationSummary(const Sequence& seq) {
  const CameraCalib& cam = seq.calib.cam0;
  const std::string model = seq.kind == DatasetKind::kKitti ? "rectified" : cam.distortion_model;
  return fmt::format("{}x{} {} b={:.3f}m", cam.width, cam.height, model, seq.calib.baseline());
}

std::string joined(const std::vector<std::string>& parts, const char* separator) {
  std::string text;
  for (const auto& part : parts) text += (text.empty() ? "" : separator) + part;
  return text;
}

// A shipped sequence as its runs see it: an image folder with its images' size (KITTI's calib.txt
// has none) and the trajectory and IMU it takes from its recording (image_folder.h).
Sequence listedSequence(const std::string& name) {
  Sequence seq = loadSequence(name, LoadOptions{false});
  if (findStereoImages(seq)) return loadImageSequence(name).sequence;
  return seq;
}

CommandRun setupList(CLI::App& app) {
  (void)app;
  return [] {
    const std::vector<std::string> names = listSequences();
    fmt::print("{:<24} {:>9} {:>9} {:>7} {:>4}  {:<35} {}\n", "sequence", "duration", "GT poses",
               "frames", "IMU", "calibration (cam0, stereo baseline)", "notes");
    int errors = 0;
    for (const std::string& name : names) {
      try {
        const Sequence seq = listedSequence(name);
        const SequenceCheck check = checkSequence(seq);
        std::string gt = seq.hasTrajectory() ? std::to_string(seq.gt.size()) : "-";
        if (seq.gt_is_estimate) gt += "*";
        fmt::print("{:<24} {:>8.1f}s {:>9} {:>7} {:>4}  {:<35} {}\n", name, check.duration_s, gt,
                   check.frames, seq.imu_file.empty() ? "no" : "yes", calibrationSummary(seq),
                   joined(check.notes, "; "));
      } catch (const InputError& e) {
        ++errors;
        fmt::print("{:<24} ERROR {}\n", name, e.what());
      }
    }
    fmt::print(
        "\n{} sequences in {}\nduration = camera timestamps span; * = the trajectory is a VIO "
        "estimate, not ground truth; IMU = real IMU recording shipped.\n",
        names.size(), datasetsRoot());
    return errors == 0 ? 0 : 1;
  };
}

struct CheckOptions {
  bool all = false;
  std::vector<std::string> targets;
};

CommandRun setupCheck(CLI::App& app) {
  auto options = std::make_shared<CheckOptions>();
  app.add_flag("--all", options->all, "check every shipped sequence");
  app.add_option("sequences", options->targets,
                 "sequence names (see `marglab datasets list`) or folders in EuRoC/TUM-VI ASL, "
                 "KITTI or shipped layout");
  return [options] {
    std::vector<std::string> targets = options->targets;
    if (options->all) {
      const std::vector<std::string> names = listSequences();
      targets.insert(targets.begin(), names.begin(), names.end());
    }
    if (targets.empty()) throw UsageError("datasets check: give --all or sequence names / folders");
    for (const std::string& target : targets) checkDatasetArgument(target);
    int failed = 0;
    std::string first_error;
    for (const std::string& target : targets) {
      try {
        const Sequence seq = loadSequence(target);
        SequenceCheck check = checkSequence(seq);
        std::string summary;
        if (check.timestamps_only) {
          summary =
              fmt::format("timestamps only: {} frames, {:.1f} s", check.frames, check.duration_s);
        } else {
          summary =
              fmt::format("{} frames ({} in trajectory), {:.1f} s, {} poses ({})", check.frames,
                          check.frames_in_gt, check.duration_s, seq.gt.size(), seq.gt_source);
        }
        if (seq.imu)
          summary += fmt::format(", IMU {} @ {:.1f} Hz", seq.imu->size(), check.imu_rate_hz);
        // What `run` loads beyond the sequence: the camera models and every image.
        const ImageSequence images = loadImageSequence(target);
        if (const std::size_t pairs = checkImages(images); pairs > 0)
          summary += fmt::format(", {} stereo image pairs decoded", pairs);
        if (images.images && images.images->unpaired_left > 0) {
          check.notes.push_back(unpairedFramesNote(*images.images));
        }
        if (!check.notes.empty()) summary += " [" + joined(check.notes, "; ") + "]";
        fmt::print("ok    {:<24} {}\n", seq.name, summary);
      } catch (const InputError& e) {
        ++failed;
        if (first_error.empty()) first_error = e.what();
        fmt::print("FAIL  {:<24} {}\n", target, e.what());
      }
    }
    std::fflush(stdout);
    if (failed > 0) {
      fmt::print(stderr, "marglab: error: {} of {} sequences failed; first: {}\n", failed,
                 targets.size(), first_error);
      return 1;
    }
    return 0;
  };
}

struct SimulateOptions {
  std::string dataset;
  uint64_t seed = 0;
  std::size_t frames = 0;
  bool no_noise = false;
  std::string profile = "ideal";
  std::string output;
};

CommandRun setupSimulate(CLI::App& app) {
  auto options = std::make_shared<SimulateOptions>();
  app.add_option("--dataset", options->dataset, "sequence name or folder")->required();
  app.add_option("--seed", options->seed, "random seed (world and tracks), in [0, 2^64 - 1]")
      ->check(seedRange());
  app.add_option("--frames", options->frames, "simulate only the first N frames (0: all)")
      ->check(nonNegativeInt("the number of frames (0: all)"));
  app.add_flag("--no-noise", options->no_noise, "exact projections: no pixel noise, no outliers");
  app.add_option("--profile", options->profile,
                 "measurement profile (sim.profile, core/sim/sim_profile.h): ideal | realistic "
                 "| realistic-motion")
      ->check(CLI::IsMember({"ideal", "realistic", "realistic-motion"}));
  app.add_option("-o,--output", options->output, "track file (.h5 / .hdf5: HDF5, else text)")
      ->required();
  return [options] {
    checkDatasetArgument(options->dataset);
    cli::checkOutputFile(options->output, "-o");
    cli::refuseOverwritingInputs({options->output}, cli::datasetInputs(options->dataset));
    const auto start = std::chrono::steady_clock::now();
    // The sequence as `run --frontend simulated` loads it: an image folder's ground truth may come
    // from the shipped sequence of its recording (image_folder.h).
    const Sequence seq = loadImageSequence(options->dataset).sequence;
    if (!seq.hasTrajectory()) {
      throw InputError(
          seq.directory, 0,
          fmt::format("{}: no trajectory (timestamps only); cannot simulate tracks", seq.name));
    }
    const TrajectorySpline spline = TrajectorySpline::fromSequence(seq);
    SimulationOptions sim = defaultSimulationOptions(seq, options->seed);
    sim.tracker.max_frames = options->frames;
    std::string profile_path;  // the realistic profile of the dataset's family, printed below
    SimProfile profile = SimProfile::kIdeal;
    parseSimProfile(options->profile, &profile);  // checked by IsMember above
    if (profile != SimProfile::kIdeal) {
      profile_path = realisticProfilePath(seq.kind, profile);
      applyRealisticProfile(readRealisticProfile(profile_path), &sim.tracker);
    }
    if (options->no_noise) {
      sim.tracker.noise = false;
      sim.tracker.outliers = false;
    }
    const TrackStream stream = simulateSequence(seq, spline, sim);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    writeTrackFile(options->output, stream);

    const TrackStatistics s = trackStatistics(stream);
    const Distribution& f = s.features_per_frame;
    const Distribution& l = s.track_length;
    fmt::print("sequence            {} (seed {}{})\n", seq.name, options->seed,
               options->no_noise ? ", no noise" : "");
    if (!profile_path.empty())
      fmt::print("profile             {} ({})\n", options->profile, profile_path);
    fmt::print("frames              {}\n", s.frames);
    fmt::print("landmarks           {} world points\n", stream.landmarks_w.size());
    fmt::print("features per frame  mean {:.1f}  median {:.0f}  min {:.0f}  max {:.0f}\n", f.mean,
               f.median, f.min, f.max);
    fmt::print(
        "track length        mean {:.1f}  median {:.0f}  p90 {:.0f}  max {:.0f}  ({} tracks)\n",
        l.mean, l.median, l.p90, l.max, s.tracks);
    fmt::print("stereo share        {:.3f}\n", s.stereo_share);
    fmt::print("outlier share       {:.4f}\n", s.outlier_share);
    fmt::print("simulation time     {:.2f} s (load, spline, world, tracks)\n", seconds);
    fmt::print("wrote               {}\n", options->output);
    return 0;
  };
}

struct TrackOptions {
  std::string dataset;
  std::size_t frames = 0;
  int passes = 1;
  std::string output;
  std::string config;
};

void printTracking(const ImageSequence& images, const ImageTracking& tracking, double best_s,
                   double best_cpu_s, int passes) {
  const TrackStatistics s = trackStatistics(tracking.stream);
  std::vector<double> tracked;
  for (const FrontendFrameStats& f : tracking.stats) tracked.push_back(f.n_tracked);
  const std::size_t n = tracking.stats.size();
  fmt::print("sequence            {} ({})\n", images.sequence.name, images.images->source);
  fmt::print("frames              {}\n", n);
  fmt::print("features per frame  mean {:.1f}  median {:.0f}  min {:.0f}  max {:.0f}\n",
             s.features_per_frame.mean, s.features_per_frame.median, s.features_per_frame.min,
             s.features_per_frame.max);
  fmt::print("tracked per frame   median {:.0f} (continued from the previous frame)\n",
             distributionOf(tracked).median);
  fmt::print(
      "track length        mean {:.1f}  median {:.0f}  p90 {:.0f}  max {:.0f}  ({} tracks)\n",
      s.track_length.mean, s.track_length.median, s.track_length.p90, s.track_length.max, s.tracks);
  fmt::print("stereo share        {:.3f}\n", s.stereo_share);
  fmt::print(
      "front-end time      {:.2f} ms/frame = {:.0f} stereo frames/s wall, {:.2f} ms/frame = "
      "{:.0f} frames/s CPU (one thread, best of {} passes; PNG decoding excluded)\n",
      1e3 * best_s / static_cast<double>(n), static_cast<double>(n) / best_s,
      1e3 * best_cpu_s / static_cast<double>(n), static_cast<double>(n) / best_cpu_s, passes);
  fmt::print("PNG decoding        {:.2f} ms/frame (both images)\n",
             1e3 * tracking.t_decode_s / static_cast<double>(n));
}

CommandRun setupTrack(CLI::App& app) {
  auto options = std::make_shared<TrackOptions>();
  app.add_option("--dataset", options->dataset,
                 "image folder: EuRoC/TUM-VI mav0/ layout or KITTI sequences/NN, or a shipped "
                 "name with images (euroc/V1_01_easy_images)")
      ->required();
  app.add_option("--frames", options->frames, "track only the first N stereo frames (0: all)")
      ->check(nonNegativeInt("the number of frames (0: all)"));
  app.add_option("--passes", options->passes,
                 "track the images this many times and report the fastest pass (timing)")
      ->check(cli::intRange("the number of passes", 1, 100));
  app.add_option("-o,--output", options->output, "track file (.h5 / .hdf5: HDF5, else text)")
      ->required();
  app.add_option("--config", options->config,
                 "TOML config whose [frontend] section sets the front-end and whose "
                 "[calibration] corrects the camera it uses, as `run` does (other sections are "
                 "checked and ignored; prediction: the tracker's own, there is no estimator)");
  return [options] {
    checkDatasetArgument(options->dataset);
    cli::checkOutputFile(options->output, "-o");
    cli::CommandInputs inputs{{options->config}, {}};
    cli::addInputs(&inputs, cli::datasetInputs(options->dataset));
    cli::refuseOverwritingInputs({options->output}, inputs);
    RunConfig config;
    if (!options->config.empty()) config.loadToml(options->config);
    config.validate();          // the relations `run` refuses (lm.lambda_min > lm.lambda_init), too
    installInterruptCleanup();  // SIGINT / SIGTERM while tracking: says so, exits 128 + signal
    ImageSequence images = loadImageSequence(options->dataset);
    applyCalibration(config.calibration, &images.sequence.calib);
    ImageTracking tracking;
    double best_s = 0, best_cpu_s = 0;
    for (int pass = 0; pass < options->passes; ++pass) {
      ImageTracking run = trackImages(images, config.frontend, options->frames);
      double total = 0, cpu = 0;
      for (const FrontendFrameStats& f : run.stats) {
        total += f.t_frontend_s;
        cpu += f.cpu_frontend_s;
      }
      if (pass == 0 || total < best_s) best_s = total;
      if (pass == 0 || cpu < best_cpu_s) best_cpu_s = cpu;
      if (pass == 0) tracking = std::move(run);  // every pass gives the same tracks
    }
    if (tracking.stats.empty()) throw InputError(options->dataset, 0, "no stereo frames");
    writeTrackFile(options->output, tracking.stream);
    printTracking(images, tracking, best_s, best_cpu_s, options->passes);
    fmt::print("wrote               {}\n", options->output);
    return 0;
  };
}

struct RenderArgs {
  std::string dataset;
  long long frames = 200;
  double start_s = 0;
  uint64_t seed = 0;
  std::string output;
};

std::string renderCommandLine(const RenderArgs& a) {
  return fmt::format("marglab datasets render --dataset {} --frames {} --start {} --seed {} -o {}",
                     a.dataset, a.frames, a.start_s, a.seed, a.output);
}

CommandRun setupRender(CLI::App& app) {
  auto options = std::make_shared<RenderArgs>();
  app.add_option("--dataset", options->dataset,
                 "shipped sequence with a trajectory (`marglab datasets list`), e.g. "
                 "euroc/V1_03_difficult, tumvi/room1, kitti/00")
      ->required();
  app.add_option("--frames", options->frames,
                 "stereo frames to render, at the sequence's camera times inside its ground truth")
      ->capture_default_str();
  app.add_option("--start", options->start_s,
                 "seconds after the first ground-truth pose at which the frames begin")
      ->capture_default_str();
  app.add_option("--seed", options->seed, "random seed (world, textures, IMU noise)")
      ->check(seedRange());
  app.add_option("-o,--output", options->output,
                 "folder to create (must not exist or be empty), in the dataset's layout")
      ->required();
  return [options] {
    if (options->output.empty())
      throw UsageError("-o is empty: expected the folder to render into");
    const auto start = std::chrono::steady_clock::now();
    const RenderPlan plan =
        planRendering(options->dataset, options->frames, options->start_s, options->seed);
    cli::refuseOverwritingInputs({options->output}, cli::datasetInputs(options->dataset));
    RenderSummary s;
    try {
      s = writeRenderedFolder(plan, options->output, renderCommandLine(*options));
    } catch (const Interrupted& e) {
      fmt::print(stderr, "marglab: {}: stopped, no folder written\n", e.what());
      return e.exitCode();
    }
    fmt::print("rendered {} stereo frames of {} ({}x{}, camera model {}) in {:.1f} s -> {}\n",
               s.frames, plan.sequence.name, s.width, s.height, s.camera_model,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
               options->output);
    return 0;
  };
}

struct StereoBiasArgs {
  std::string dataset;
  std::string frames;
  std::string config;
  std::string poses;
  std::string output;
};

// "A:B" → (A, B) with 0 <= A <= B; "" → the whole folder (−1, −1).
std::pair<int, int> parseFrameRange(const std::string& text) {
  if (text.empty()) return {-1, -1};
  const std::size_t colon = text.find(':');
  try {
    std::size_t end_a = 0, end_b = 0;
    const int a = std::stoi(text.substr(0, colon), &end_a);
    const int b = std::stoi(text.substr(colon + 1), &end_b);
    if (colon != std::string::npos && end_a == colon && end_b == text.size() - colon - 1 &&
        a >= 0 && a <= b) {
      return {a, b};
    }
  } catch (const std::exception&) {  // not a number, or out of int's range: the message below
  }
  throw UsageError("--frames " + text +
                   ": expected FIRST:LAST, frame indices with 0 <= FIRST <= LAST (inclusive)");
}

std::string stereoBiasCommandLine(const StereoBiasArgs& a) {
  std::string line = "marglab datasets stereo-bias --dataset " + a.dataset;
  if (!a.frames.empty()) line += " --frames " + a.frames;
  if (!a.config.empty()) line += " --config " + a.config;
  if (!a.poses.empty()) line += " --poses " + a.poses;
  return line + " -o " + a.output;
}

int runStereoBias(const StereoBiasArgs& options) {
  const auto [first, last] = parseFrameRange(options.frames);
  checkDatasetArgument(options.dataset);
  cli::checkOutputFile(options.output, "-o");
  cli::CommandInputs inputs{{options.config, options.poses}, {}};
  cli::addInputs(&inputs, cli::datasetInputs(options.dataset));
  cli::refuseOverwritingInputs({options.output}, inputs);
  RunConfig config;
  if (!options.config.empty()) config.loadToml(options.config);
  config.validate();
  installInterruptCleanup();
  ImageSequence images = loadImageSequence(options.dataset);
  applyCalibration(config.calibration, &images.sequence.calib);
  const int n = images.images ? static_cast<int>(images.images->t_ns.size()) : 0;
  StereoBiasRequest request;
  request.dataset = options.dataset;
  request.frontend = config.frontend;
  request.config_shift_px = config.calibration.right_cx_shift_px;
  request.first = first < 0 ? 0 : first;
  request.last = last < 0 ? n - 1 : last;
  if (!options.poses.empty()) {
    request.poses = readTumTrajectory(options.poses);
    request.poses_file = options.poses;
  }
  const StereoBiasStudy study = measureStereoBias(images, request);
  writeFileAtomically(options.output, stereoBiasToml(study, stereoBiasCommandLine(options)));
  fmt::print("{}wrote {}\n", stereoBiasReport(study), options.output);
  return 0;
}

CommandRun setupStereoBias(CLI::App& app) {
  auto options = std::make_shared<StereoBiasArgs>();
  app.add_option("--dataset", options->dataset,
                 "KITTI-layout folder with ground-truth poses (calib.txt, times.txt, poses.txt, "
                 "image_0/, image_1/; or the download's sequences/NN), or a shipped name "
                 "(kitti/06_images)")
      ->required();
  app.add_option("--frames", options->frames,
                 "FIRST:LAST, the frames measured (0-based, inclusive; default: all); the images "
                 "are tracked from frame 0 on");
  app.add_option("--config", options->config,
                 "TOML config whose [frontend] sets the front-end and whose [calibration] the "
                 "camera it tracks with, as `run` does; the fragment then holds the total shift");
  app.add_option("-o,--output", options->output,
                 "config fragment to write: the report as comments, [calibration] "
                 "right_cx_shift_px")
      ->required();
  app.add_option("--poses", options->poses,
                 "TUM trajectory of the left camera (t x y z qx qy qz qw, e.g. RUN.tum of `marglab "
                 "run`) instead of the ground truth: the offset is then the fit's intercept c, "
                 "which the trajectory's scale cannot absorb");
  return [options] { return runStereoBias(*options); };
}

struct ImuHoldArgs {
  std::string dataset;
  std::string noise_profile = "kalibr";
};

// Quantiles of one field of the intervals, printed in `scale` units.
std::string holdQuantiles(std::vector<double> v, double scale) {
  std::sort(v.begin(), v.end());
  const auto q = [&](double p) { return scale * v[static_cast<std::size_t>(p * (v.size() - 1))]; };
  return fmt::format("{:10.3g} {:10.3g} {:10.3g} {:10.3g}", q(0.5), q(0.9), q(0.99),
                     v.back() * scale);
}

int runImuHold(const ImuHoldArgs& options) {
  const Sequence seq = loadSequence(options.dataset);
  if (!seq.hasTrajectory() || seq.kind == DatasetKind::kKitti) {
    throw InputError(seq.directory, 0,
                     "imu-hold: expected an EuRoC or TUM-VI sequence with a trajectory");
  }
  ImuNoiseProfile profile = ImuNoiseProfile::kKalibr;
  parseImuNoiseProfile(options.noise_profile, &profile);  // checked by IsMember
  const ImuNoise noise = profileImuNoise(seq, profile);
  const TrajectorySpline spline = TrajectorySpline::fromSequence(seq);
  fmt::print(
      "{}: noise-free synthetic IMU (200 Hz) preintegrated over each frame interval, "
      "residual at the spline's true states; chi2 whitened with the {} densities\n",
      seq.name, options.noise_profile);
  fmt::print("{:28s} {:>10s} {:>10s} {:>10s} {:>10s}\n", "", "median", "p90", "p99", "max");
  for (const double shift : {0.0, 0.0025}) {
    const std::vector<ImuHoldInterval> h =
        imuHoldErrors(spline, seq.cam_t_ns, noise, gravityWorld(seq.kind), 200.0, shift);
    std::vector<double> rot, vel, pos, chi2;
    for (const ImuHoldInterval& x : h) {
      rot.push_back(x.rot_rad), vel.push_back(x.vel_mps), pos.push_back(x.pos_m);
      chi2.push_back(x.chi2);
    }
    fmt::print("samples at t_k + {:.1f} ms ({} intervals)\n", shift * 1e3, h.size());
    fmt::print("  {:26s} {}\n", "|r_R| [deg]", holdQuantiles(rot, 180.0 / M_PI));
    fmt::print("  {:26s} {}\n", "|r_v| [mm/s]", holdQuantiles(vel, 1e3));
    fmt::print("  {:26s} {}\n", "|r_p| [mm]", holdQuantiles(pos, 1e3));
    fmt::print("  {:26s} {}\n", "chi2 (noise: 9 on average)", holdQuantiles(chi2, 1.0));
  }
  return 0;
}

CommandRun setupImuHold(CLI::App& app) {
  auto options = std::make_shared<ImuHoldArgs>();
  app.add_option("--dataset", options->dataset, "EuRoC or TUM-VI sequence name or folder")
      ->required();
  app.add_option("--noise-profile", options->noise_profile,
                 "IMU densities that whiten the residual (imu.noise_profile): kalibr | basalt")
      ->check(CLI::IsMember({"kalibr", "basalt"}));
  return [options] {
    checkDatasetArgument(options->dataset);
    return runImuHold(*options);
  };
}

struct SubVerb {
  const char* name;
  const char* description;
  CommandRun (*setup)(CLI::App&);
};

const SubVerb kSubVerbs[] = {
    {"list", "table of the shipped sequences: duration, GT, frames, IMU, calibration", setupList},
    {"check", "load and validate sequences (names or folders); exit 1 on bad input", setupCheck},
    {"simulate", "simulated stereo feature tracks along a sequence's trajectory -> track file",
     setupSimulate},
    {"track", "the image front-end on a folder's stereo images -> track file + speed", setupTrack},
    {"render",
     "stereo images rendered along a sequence's trajectory through its real camera model -> a "
     "dataset folder in its original layout",
     setupRender},
    {"imu-hold",
     "the estimator's zero-order hold on the noise-free synthetic IMU against the trajectory's "
     "true states, per frame interval (core/sim/imu_hold.h)",
     setupImuHold},
    {"stereo-bias",
     "a KITTI folder's stereo disparities against motion stereo (ground-truth poses) -> report "
     "+ config fragment [calibration] right_cx_shift_px",
     setupStereoBias},
};

const bool kRegistered = registerCommand(
    {"datasets", "the real datasets: list, check, simulate, track, render, imu-hold, stereo-bias",
     60, [](CLI::App& app) -> CommandRun {
       app.require_subcommand(1);
       auto runs = std::make_shared<std::vector<std::pair<CLI::App*, CommandRun>>>();
       for (const SubVerb& verb : kSubVerbs) {
         CLI::App* sub = app.add_subcommand(verb.name, verb.description);
         runs->emplace_back(sub, verb.setup(*sub));
       }
       return [runs] {
         for (auto& [sub, run] : *runs) {
           if (sub->parsed()) return run();
         }
         return 2;
       };
     }});

}  // namespace
}  // namespace marglab::cli
