#include "core/pipeline/run.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>

#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/diagnostics/ate.h"
#include "core/diagnostics/diagnostics.h"
#include "core/estimator/estimator.h"
#include "core/estimator/window_io.h"
#include "core/imu/noise_profile.h"
#include "core/pipeline/tracking_monitor.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/imu_synth.h"
#include "core/sim/trajectory_spline.h"

namespace marglab {
namespace {

SE3<double> cameraExtrinsic(const CameraCalib& camera) {
  return SE3<double>(camera.R_b_c, camera.t_b_c);
}

}  // namespace

StereoRig<double> rigFromCalib(const StereoCalib& calib) {
  StereoRig<double> rig;
  auto camera = [](const CameraCalib& c) {
    return PinholeCamera<double>{c.fx, c.fy, c.cx, c.cy, c.width, c.height};
  };
  rig.cam0 = camera(calib.cam0);
  rig.cam1 = camera(calib.cam1);
  rig.T_i_c0 = cameraExtrinsic(calib.cam0);
  rig.T_i_c1 = cameraExtrinsic(calib.cam1);
  return rig;
}

namespace {

// The ground truth of the left camera: T_w_c0 = T_w_b T_b_c0 at every GT sample.
Trajectory cameraGroundTruth(const Trajectory& gt, const SE3<double>& T_b_c0) {
  Trajectory cam;
  for (size_t i = 0; i < gt.size(); ++i) {
    const SE3<double> T_w_c = SE3<double>(gt.q_w_b[i], gt.p_w_b[i]) * T_b_c0;
    cam.push_back(gt.t_ns[i], T_w_c.translation(), T_w_c.unitQuaternion());
  }
  return cam;
}

std::string splitDataset(const Sequence& sequence) { return datasetKindName(sequence.kind); }

TrackSourceOptions trackSourceOptions(const RunOptions& options) {
  TrackSourceOptions source;
  source.dataset = options.dataset;
  source.frontend = options.frontend;
  source.tracks_file = options.tracks_file;
  source.max_frames = options.max_frames;
  source.seed = options.seed;
  source.sim_profile = options.config.sim_profile;
  source.frontend_options = options.config.frontend;
  return source;
}

// The synthetic IMU's random stream is separate from the world's and the tracks'.
std::uint64_t imuSeed(std::uint64_t seed) { return seed ^ 0x9e3779b97f4a7c15ULL; }

}  // namespace

ImuSetup vioImuSetup(const RunOptions& options, const Sequence& sequence,
                     const TrajectoryFunction& trajectory, std::int64_t t0_ns,
                     std::map<std::string, std::string>* provenance) {
  ImuSetup setup;
  // One set of densities for the synthetic IMU and the estimator's weights.
  setup.noise = profileImuNoise(sequence, options.config.imu_noise_profile);
  setup.g_w = gravityWorld(sequence.kind);
  const TrajectorySample first = trajectory.evaluate(t0_ns);
  setup.initial.t_ns = t0_ns;
  setup.initial.T_w_i = SE3<double>(first.R_w_b, first.p_w_b);
  setup.initial.v_w = first.v_w;
  if (options.imu == ImuSource::kReal) {
    setup.imu = realImuWithin(sequence, trajectory);
    if (setup.imu.size() < 2) {
      throw InputError(sequence.imu_file, 0, "fewer than two IMU samples inside the trajectory");
    }
    std::vector<std::int64_t> dt;
    for (size_t k = 1; k < setup.imu.size(); ++k) {
      dt.push_back(setup.imu.t_ns[k] - setup.imu.t_ns[k - 1]);
    }
    std::nth_element(dt.begin(), dt.begin() + dt.size() / 2, dt.end());
    setup.sample_period_s = 1e-9 * static_cast<double>(dt[dt.size() / 2]);
    std::string biases = "zero";
    if (sequence.gt_imu_state && !sequence.gt_imu_state->bias_gyro.empty()) {
      const auto& gt_t = sequence.gt.t_ns;
      const size_t k =
          static_cast<size_t>(std::lower_bound(gt_t.begin(), gt_t.end(), t0_ns) - gt_t.begin());
      const size_t i = std::min(k, gt_t.size() - 1);
      setup.initial.b_g = sequence.gt_imu_state->bias_gyro[i];
      setup.initial.b_a = sequence.gt_imu_state->bias_accel[i];
      biases = "ground-truth csv";
    }
    (*provenance)["imu"] =
        fmt::format("real, {} ({:.1f} Hz)", sequence.imu_file, 1.0 / setup.sample_period_s);
    (*provenance)["initial_biases"] = biases;
  } else {
    ImuSynthOptions synth_options;
    synth_options.gravity_w = setup.g_w;
    setup.imu =
        synthesizeImu(trajectory, setup.noise, 200.0, imuSeed(options.seed), synth_options).imu;
    setup.sample_period_s = 1.0 / 200.0;
    (*provenance)["imu"] = "synthetic 200 Hz from the spline (white noise + bias random walk)";
    (*provenance)["initial_biases"] = "zero (the synthetic biases start at zero)";
  }
  (*provenance)["initial_state"] = "ground-truth pose and velocity at the first frame";
  (*provenance)["imu_noise"] = fmt::format(
      "{} profile: gyro {:g} rad/s/sqrt(Hz), gyro bias walk {:g}, accel {:g} m/s^2/sqrt(Hz), "
      "accel bias walk {:g}",
      toString(options.config.imu_noise_profile), setup.noise.gyro_noise_density,
      setup.noise.gyro_random_walk, setup.noise.accel_noise_density, setup.noise.accel_random_walk);
  return setup;
}

namespace {

// The root attributes of a run's results file: what ran, on what, with which settings.
template <typename Scalar>
RunMetadata runMetadata(const RunOptions& options, const TrackSource& source,
                        const EstimatorConfig& config, bool vio,
                        const std::map<std::string, std::string>& imu_provenance) {
  const Sequence& sequence = source.sequence;
  RunMetadata metadata;
  metadata.dataset = splitDataset(sequence);
  const std::string& name = sequence.name;
  metadata.sequence = name.substr(name.find('/') == std::string::npos ? 0 : name.find('/') + 1);
  metadata.variant = options.variant.name();
  metadata.precision = options.variant.precisionName();
  metadata.mode = vio ? "vio" : "vo";
  metadata.seed = options.seed;
  metadata.config_toml = config.toToml();
  metadata.marg_strategy = toString(config.marg_strategy);
  if (options.variant.marg == MargMethod::kQr) {
    metadata.qr_threshold_mode = toString(config.qr_threshold_mode);
    metadata.qr_threshold = config.qr_threshold >= 0
                                ? config.qr_threshold
                                : static_cast<double>(NumericTraits<Scalar>::sqrtEpsilon());
  }
  metadata.frontend = source.frontend;
  metadata.extra = {{"dataset_path", sequence.directory},
                    {"gt_source", source.has_ground_truth ? sequence.gt_source : "none"}};
  for (const auto& [key, value] : source.provenance) metadata.extra.emplace_back(key, value);
  for (const auto& [key, value] : imu_provenance) metadata.extra.emplace_back(key, value);
  return metadata;
}

// The gauge diagnostics of one marginalization event (/marg) and, every store_prior_every
// events, the prior itself.
void writeMargEvent(const MargEvent& event, int frame_index, std::int64_t t_ns,
                    std::int64_t marg_index, const RunOptions& options,
                    const EstimatorConfig& config, ResultsWriter& writer) {
  const PriorLayout& layout = event.layout;
  const GaugeState& state = event.state;
  const std::uint64_t seed = config.diagnostics_seed + static_cast<std::uint64_t>(marg_index);
  const bool sqrt_storage = sqrtStorage(options.variant.storage);
  const PriorDiagnostics diagnostics =
      sqrt_storage ? diagnoseSqrtPrior(event.J_m, event.r_m, layout, state, seed)
                   : diagnosePrior(event.H_m, event.b_m, layout, state, seed);
  writer.appendMarg(makeMargRecord(frame_index, t_ns, event.prior_rows, diagnostics));
  if (config.store_prior_every > 0 && marg_index % config.store_prior_every == 0) {
    writer.appendPriorMatrices(marg_index, layout, event.H_m, event.b_m,
                               sqrt_storage ? &event.J_m : nullptr,
                               sqrt_storage ? &event.r_m : nullptr);
  }
}

// A captured window (--dump-windows) into the dump folder.
void writeCapturedWindow(WindowSnapshot window, const RunOptions& options, int frame_index) {
  window.dataset = options.dataset;
  window.frame_index = frame_index;
  writeWindow(window, (std::filesystem::path(options.dump_dir) /
                       windowFileName(options.dataset, options.variant.name(), frame_index))
                          .string());
}

// Why the run fails at this frame ("" when it goes on): a numerical failure of the estimator, or
// a position error beyond the dataset's bound.
std::string frameFailure(const FrameResult& result, const FrameRecord& record,
                         const EstimatorConfig& config) {
  if (!result.status.ok()) return result.status.toString();
  if (std::isfinite(record.p_gt.x()) &&
      (record.p_est - record.p_gt).norm() > config.max_position_error_m) {
    return fmt::format("position error {:.2f} m exceeds the bound of {:.1f} m",
                       (record.p_est - record.p_gt).norm(), config.max_position_error_m);
  }
  return "";
}

// The front-end's prediction of the frame at t_ns from the estimator (motion_prediction.h): the
// predicted motion of cam0 since the newest frame, and the window's landmarks in that frame's
// cam0. T_i_c0: body → cam0 (VO: the identity, the state is cam0).
template <typename Scalar>
std::optional<FramePrediction> estimatorPrediction(const SlidingWindowEstimator<Scalar>& estimator,
                                                   std::int64_t t_ns, const SE3<double>& T_i_c0) {
  const std::optional<SE3<double>> newest = estimator.newestPose();
  const std::optional<SE3<double>> predicted = estimator.predictPose(t_ns);
  if (!newest || !predicted) return std::nullopt;
  const SE3<double> T_c0prev_w = (*newest * T_i_c0).inverse();
  FramePrediction prediction;
  prediction.T_new_prev = (*predicted * T_i_c0).inverse() * T_c0prev_w.inverse();
  for (const auto& [id, p_w] : estimator.landmarkPoints()) {
    prediction.p_prev.emplace(id, T_c0prev_w * p_w);
  }
  return prediction;
}

// What one run writes besides the frame loop's records: TUM trajectory columns and counters.
struct RunTrace {
  std::vector<std::int64_t> t_ns;
  std::vector<Eigen::Vector3d> positions;
  std::vector<Eigen::Quaterniond> quaternions;
  std::int64_t marg_index = 0;
  double features = 0;
  int processed = 0;
};

// The records of one processed frame: /frames, /marg, /sparsify, the trajectory.
void recordFrame(int k, const TrackFrame& frame, const FrameResult& result, FrameRecord record,
                 const RunOptions& options, const EstimatorConfig& config, ResultsWriter& writer,
                 RunTrace* trace, RunOutcome* outcome) {
  writer.appendFrame(record);
  trace->t_ns.push_back(frame.t_ns);
  trace->positions.push_back(record.p_est);
  trace->quaternions.push_back(record.q_est);
  if (result.marg_event && result.status.ok() && !result.marg_event->layout.empty()) {
    writeMargEvent(*result.marg_event, k, frame.t_ns, trace->marg_index++, options, config,
                   writer);
  }
  if (result.sparsify_event && result.status.ok()) {
    const SparsifyEvent& event = *result.sparsify_event;
    SparsifyRecord record = event;  // the event's /sparsify row, located in /frames here
    record.frame_index = k;
    record.t_ns = frame.t_ns;
    writer.appendSparsify(record);
    ++outcome->n_keyframe_events;
    if (!event.fallback_reason.empty()) {
      fmt::print(stderr, "frame {}: nfr kept the dense prior: {}\n", k, event.fallback_reason);
    }
  }
}

template <typename Scalar>
RunOutcome runWith(const RunOptions& options, TrackSource& source) {
  const EstimatorConfig& config = options.config;
  const Sequence& sequence = source.sequence;
  const TrajectoryFunction& trajectory = *source.trajectory;
  RunOutcome outcome;
  outcome.frontend = source.frontend;
  const bool vio = options.mode == RunMode::kVio;
  outcome.vio = vio;
  outcome.marg_strategy = config.marg_strategy;
  const SE3<double> T_b_c0 = cameraExtrinsic(sequence.calib.cam0);
  // VIO estimates the body (IMU) frame, VO the left camera: the ATE compares like with like.
  const Trajectory gt_est = vio ? sequence.gt : cameraGroundTruth(sequence.gt, T_b_c0);
  const std::int64_t t0_ns = source.frameTimeNs(0);
  const TrajectorySample first = trajectory.evaluate(t0_ns);
  const SE3<double> T_w_c0_first = SE3<double>(first.R_w_b, first.p_w_b) * T_b_c0;
  std::map<std::string, std::string> imu_provenance;
  std::optional<ImuSetup> imu;
  if (vio) imu = vioImuSetup(options, sequence, trajectory, t0_ns, &imu_provenance);

  ResultsWriter writer = ResultsWriter::create(
      options.output, runMetadata<Scalar>(options, source, config, vio, imu_provenance));
  SlidingWindowEstimator<Scalar> estimator(config, options.variant, rigFromCalib(sequence.calib),
                                           T_w_c0_first, std::move(imu));
  const bool predict = source.images && config.frontend.prediction == MotionPredictionSource::kEstimator;
  const SE3<double> T_i_c0 = vio ? T_b_c0 : SE3<double>();
  TrackingMonitor monitor(config);
  // Simulated tracks cannot lose the scene: where they thin out (the simulated world ends a few
  // metres past the trajectory's end) it is the simulation's edge, not a tracking failure.
  const bool watch_tracking = source.frontend != "simulated";
  RunTrace trace;
  const int total = static_cast<int>(source.n_frames);
  std::string failure_kind;
  for (int k = 0; k < total; ++k) {
    ++trace.processed;
    std::optional<FramePrediction> prediction;
    if (predict) prediction = estimatorPrediction(estimator, source.frameTimeNs(k), T_i_c0);
    TrackFrame frame = source.frame(k, prediction ? &*prediction : nullptr);
    if (k == options.inject_nan_frame && !frame.observations.empty()) {
      frame.observations.front().uv0.x() = std::numeric_limits<double>::quiet_NaN();
    }
    trace.features += static_cast<double>(frame.observations.size());
    const bool dump = std::find(options.dump_windows.begin(), options.dump_windows.end(), k) !=
                      options.dump_windows.end();
    if (dump) estimator.captureNextWindow();
    const FrameResult result = estimator.processFrame(frame);
    if (std::optional<WindowSnapshot> window = estimator.takeCapturedWindow()) {
      writeCapturedWindow(std::move(*window), options, k);
    }
    FrameRecord record = result;  // the result's /frames row
    if (auto p_gt = interpolatePosition(gt_est, frame.t_ns)) record.p_gt = *p_gt;
    recordFrame(k, frame, result, record, options, config, writer, &trace, &outcome);
    if (options.progress) options.progress(k + 1, total);

    std::string failure = frameFailure(result, record, config);
    failure_kind = "numerical";
    if (failure.empty() && result.status.ok() && watch_tracking) {
      failure = monitor.update(k, result);
      failure_kind = "tracking";
    }
    if (!failure.empty()) {
      outcome.status = RunStatus::kFailed;
      outcome.failure_frame = k;
      outcome.failure_reason = failure;
      outcome.failure_kind = failure_kind;
      break;
    }
  }
  writer.writeFrontend(frontendRecords(source.frontendStats()));
  outcome.frontend_summary = frontendSummary(source.frontend, source.frontendStats());
  outcome.mean_features_per_frame = trace.processed > 0 ? trace.features / trace.processed : 0;
  outcome.summary = writer.finish(RunSummary{}, outcome.status, outcome.failure_frame,
                                  outcome.failure_reason, outcome.failure_kind);
  outcome.tum_path = tumPathFor(options.output);
  writeTumTrajectory(outcome.tum_path, trace.t_ns, trace.positions, trace.quaternions);
  return outcome;
}

}  // namespace

std::string windowFileName(const std::string& dataset, const std::string& variant, int frame) {
  std::string name = dataset;
  for (char& c : name) {
    if (c == '/' || c == '\\' || c == ' ') c = '-';
  }
  while (!name.empty() && (name.front() == '.' || name.front() == '-')) name.erase(0, 1);
  return fmt::format("{}_{}_{:06d}.win.gz", name, variant, frame);
}

std::string tumPathFor(const std::string& results_path) {
  const std::string suffix = ".h5";
  std::string base = results_path;
  if (base.size() > suffix.size() &&
      base.compare(base.size() - suffix.size(), suffix.size(), suffix) == 0) {
    base.resize(base.size() - suffix.size());
  }
  return base + ".tum";
}

RunOptions resolveRunOptions(const RunOptions& options, const Sequence& sequence,
                             bool has_ground_truth) {
  RunOptions resolved = options;
  EstimatorConfig& config = resolved.config;
  config.frontend = resolveFrontendOptions(config.frontend, sequence.kind);
  if (config.min_frames_after_kf < 0)
    config.min_frames_after_kf = sequence.defaults.min_frames_after_kf;
  if (config.max_position_error_m < 0) {
    config.max_position_error_m = sequence.defaults.max_position_error_m;
  }
  if (resolved.mode == RunMode::kAuto) {
    // Without ground truth there is no initial velocity and gravity direction: VO.
    resolved.mode =
        sequence.kind == DatasetKind::kKitti || !has_ground_truth ? RunMode::kVo : RunMode::kVio;
  }
  const std::vector<Problem> problems = runProblems(resolved, sequence, has_ground_truth);
  if (!problems.empty()) throwProblems(problems);
  return resolved;
}

std::vector<Problem> runProblems(const RunOptions& options, const Sequence& sequence,
                                 bool has_ground_truth) {
  std::vector<Problem> out = options.config.locatedProblems();
  const auto usage = [&out](std::string message) {
    out.push_back({ProblemKind::kUsage, "", 0, std::move(message)});
  };
  if (!options.tracks_file.empty() && options.frontend != FrontendKind::kAuto) {
    usage(
        fmt::format("--tracks FILE and --frontend {} both say where the tracks come from: give "
                    "one of them",
                    options.frontend == FrontendKind::kImages ? "images" : "simulated"));
  }
  // A window the run can never reach would be captured silently never.
  const int frames =
      options.max_frames > 0 ? options.max_frames : static_cast<int>(sequence.cam_t_ns.size());
  for (const int frame : options.dump_windows) {
    if (frame >= frames) {
      usage(fmt::format("--dump-windows {}: the run has {} frames ({}), expected indices below",
                        frame, frames, options.max_frames > 0 ? "--frames" : sequence.name));
    }
  }
  const bool vio = options.mode == RunMode::kVio;
  if (vio && !has_ground_truth) {
    out.push_back({ProblemKind::kInput, sequence.directory, 0,
                   "VIO starts from the ground-truth state at its first frame, and this sequence "
                   "has no ground truth (use --mode vo)"});
  }
  if (vio && sequence.kind == DatasetKind::kKitti) {
    out.push_back({ProblemKind::kInput, sequence.directory, 0,
                   "KITTI odometry has no IMU: VIO needs EuRoC or TUM-VI (use --mode vo)"});
  }
  if (!vio && options.imu == ImuSource::kReal) usage("--imu real needs VIO (--mode vio)");
  const MargStrategy strategy = options.config.marg_strategy;
  if (strategy != MargStrategy::kDiscard && !vio) {
    usage(
        fmt::format("marginalization strategy {} needs VIO (EuRoC or TUM-VI)", toString(strategy)));
  }
  // A square-root prior is positive semidefinite already: the option would silently do nothing.
  if (options.config.psd_hessian_prior && sqrtStorage(options.variant.storage)) {
    out.push_back(options.config.located(
        {"marginalization.psd_hessian_prior",
         fmt::format("marginalization.psd_hessian_prior = true with variant {}: expected a "
                     "Hessian prior storage (sq, sqp, sqj); a square-root prior is positive "
                     "semidefinite by construction",
                     options.variant.name())}));
  }
  // A captured window holds hosted landmarks and a prior over frame states only.
  if (strategy != MargStrategy::kDiscard && !options.dump_windows.empty()) {
    usage("window capture (--dump-windows) needs marginalization strategy discard");
  }
  return out;
}

RunOutcome runSequence(const RunOptions& options) {
  TrackSource source = obtainTracks(trackSourceOptions(options));
  const RunOptions resolved = resolveRunOptions(options, source.sequence, source.has_ground_truth);
  if (options.variant.floatState()) return runWith<float>(resolved, source);
  return runWith<double>(resolved, source);
}

}  // namespace marglab
