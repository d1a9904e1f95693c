#include "core/pipeline/run.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>

#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/common/statistics.h"
#include "core/data/sequence.h"
#include "core/diagnostics/ate.h"
#include "core/diagnostics/diagnostics.h"
#include "core/estimator/estimator.h"
#include "core/estimator/marg_rounding.h"
#include "core/estimator/window_io.h"
#include "core/imu/noise_profile.h"
#include "core/pipeline/motion_check.h"
#include "core/pipeline/tracking_monitor.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/imu_synth.h"
#include "core/sim/track_io.h"
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

TrackSourceOptions trackSourceOptions(const RunSpec& spec) {
  TrackSourceOptions source;
  source.dataset = spec.dataset;
  source.frontend = spec.frontend;
  source.tracks_file = spec.tracks_file;
  source.max_frames = spec.max_frames;
  source.seed = spec.seed;
  source.sim_profile = spec.config.sim_profile;
  source.sim_overrides = spec.config.sim_overrides;
  source.frontend_options = spec.config.frontend;
  return source;
}

// The synthetic IMU's random stream is separate from the world's and the tracks'.
std::uint64_t imuSeed(std::uint64_t seed) { return seed ^ 0x9e3779b97f4a7c15ULL; }

}  // namespace

ImuSetup vioImuSetup(const RunSpec& spec, const Sequence& sequence,
                     const TrajectoryFunction& trajectory, std::int64_t t0_ns,
                     std::map<std::string, std::string>* provenance) {
  ImuSetup setup;
  // One set of densities for the synthetic IMU and the estimator's weights.
  setup.noise = profileImuNoise(sequence, spec.config.estimator.imu_noise_profile);
  setup.g_w = gravityWorld(sequence.kind);
  const TrajectorySample first = trajectory.evaluate(t0_ns);
  setup.initial.t_ns = t0_ns;
  setup.initial.T_w_i = SE3<double>(first.R_w_b, first.p_w_b);
  setup.initial.v_w = first.v_w;
  if (spec.imu == ImuSource::kReal) {
    setup.imu = realImuWithin(sequence, trajectory);
    if (setup.imu.size() < 2) {
      throw InputError(sequence.imu_file, 0, "fewer than two IMU samples inside the trajectory");
    }
    setup.sample_period_s = 1e-9 * static_cast<double>(medianGapNs(setup.imu.t_ns));
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
    const bool midpoint = spec.config.sim_imu_sample_time == ImuSampleTime::kMidpoint;
    synth_options.sample_shift_s = midpoint ? 0.5 / 200.0 : 0.0;
    setup.imu =
        synthesizeImu(trajectory, setup.noise, 200.0, imuSeed(spec.seed), synth_options).imu;
    setup.sample_period_s = 1.0 / 200.0;
    (*provenance)["imu"] = std::string(
                               "synthetic 200 Hz from the spline (white noise + bias "
                               "random walk)") +
                           (midpoint ? ", each sample at the midpoint of its hold" : "");
    (*provenance)["initial_biases"] = "zero (the synthetic biases start at zero)";
  }
  (*provenance)["initial_state"] = "ground-truth pose and velocity at the first frame";
  (*provenance)["imu_noise"] = fmt::format(
      "{} profile: gyro {:g} rad/s/sqrt(Hz), gyro bias walk {:g}, accel {:g} m/s^2/sqrt(Hz), "
      "accel bias walk {:g}",
      toString(spec.config.estimator.imu_noise_profile), setup.noise.gyro_noise_density,
      setup.noise.gyro_random_walk, setup.noise.accel_noise_density, setup.noise.accel_random_walk);
  return setup;
}

namespace {

// The root attributes of a run's results file: what ran, on what, with which settings.
template <typename Scalar>
RunMetadata runMetadata(const RunSpec& spec, const TrackSource& source, const RunConfig& config,
                        bool vio, const std::map<std::string, std::string>& imu_provenance,
                        const std::string& spec_toml) {
  const Sequence& sequence = source.sequence;
  RunMetadata metadata;
  metadata.dataset = splitDataset(sequence);
  const std::string& name = sequence.name;
  metadata.sequence = name.substr(name.find('/') == std::string::npos ? 0 : name.find('/') + 1);
  metadata.variant = spec.variant.name();
  metadata.precision = spec.variant.precisionName();
  metadata.mode = vio ? "vio" : "vo";
  metadata.seed = spec.seed;
  metadata.config_toml = config.toToml();
  metadata.marg_strategy = toString(config.estimator.marg_strategy);
  if (spec.variant.marg == MargMethod::kQr) {
    metadata.qr_threshold_mode = toString(config.estimator.qr_threshold_mode);
    metadata.qr_threshold = config.estimator.qr_threshold >= 0
                                ? config.estimator.qr_threshold
                                : static_cast<double>(NumericTraits<Scalar>::sqrtEpsilon());
  }
  metadata.frontend = source.frontend;
  if (source.frontend == "tracks") {
    metadata.tracks_file = spec.tracks_file;
    metadata.tracks_sequence = source.stream.sequence;
    metadata.tracks_any_sequence = spec.tracks_any_sequence ? "true" : "false";
  }
  metadata.extra = {{"dataset_path", sequence.directory},
                    {"gt_source", source.has_ground_truth ? sequence.gt_source : "none"},
                    {"run_spec", spec_toml}};
  for (const auto& [key, value] : source.provenance) metadata.extra.emplace_back(key, value);
  for (const auto& [key, value] : imu_provenance) metadata.extra.emplace_back(key, value);
  return metadata;
}

// The gauge diagnostics of one marginalization event (/marg) and, every store_prior_every
// events, the prior itself.
void writeMargEvent(const MargEvent& event, int frame_index, std::int64_t t_ns,
                    std::int64_t marg_index, const RunSpec& spec, const RunConfig& config,
                    ResultsWriter& writer) {
  const PriorLayout& layout = event.layout;
  const GaugeState& state = event.state;
  const std::uint64_t seed = config.diagnostics.seed + static_cast<std::uint64_t>(marg_index);
  const bool sqrt_storage = sqrtStorage(spec.variant.storage);
  const PriorDiagnostics diagnostics =
      sqrt_storage ? diagnoseSqrtPrior(event.J_m, event.r_m, layout, state, seed)
                   : diagnosePrior(event.H_m, event.b_m, layout, state, seed);
  writer.appendMarg(makeMargRecord(frame_index, t_ns, event.prior_rows, diagnostics));
  if (config.diagnostics.store_prior_every > 0 &&
      marg_index % config.diagnostics.store_prior_every == 0) {
    writer.appendPriorMatrices(marg_index, layout, event.H_m, event.b_m,
                               sqrt_storage ? &event.J_m : nullptr,
                               sqrt_storage ? &event.r_m : nullptr);
  }
}

// A captured window (--dump-windows) into the dump folder.
void writeCapturedWindow(WindowSnapshot window, const RunSpec& spec, int frame_index) {
  window.dataset = spec.dataset;
  window.frame_index = frame_index;
  writeWindow(window, (std::filesystem::path(spec.dump_dir) /
                       windowFileName(spec.dataset, spec.variant.name(), frame_index))
                          .string());
}

// Why the run fails at this frame ("" when it goes on): a numerical failure of the estimator, or
// a position error beyond the dataset's bound.
std::string frameFailure(const FrameResult& result, const FrameRecord& record,
                         const RunConfig& config) {
  if (!result.status.ok()) return result.status.toString();
  if (std::isfinite(record.p_gt.x()) &&
      (record.p_est - record.p_gt).norm() > config.failure.max_position_error_m) {
    return fmt::format("position error {:.2f} m exceeds the bound of {:.1f} m",
                       (record.p_est - record.p_gt).norm(), config.failure.max_position_error_m);
  }
  return "";
}

// Why a run fails at a frame, and the failure's kind: a failed step or the ground-truth bound
// ("numerical"), else, on real measurements, the tracking monitor and the motion check
// ("tracking"). Simulated tracks cannot lose the scene: where they thin out (the simulated world
// ends a few metres past the trajectory's end) it is the simulation's edge, not a tracking
// failure; nor can they come out of order.
class FailureWatch {
 public:
  FailureWatch(const RunConfig& config, bool real_measurements)
      : config_(config),
        real_measurements_(real_measurements),
        monitor_(config.failure),
        motion_(config.failure) {}

  // "" while the run goes on; else the reason, and *kind.
  std::string update(int k, const FrameResult& result, const FrameRecord& record,
                     std::string* kind) {
    *kind = "numerical";
    std::string failure = frameFailure(result, record, config_);
    if (!failure.empty() || !real_measurements_) return failure;
    *kind = "tracking";
    failure = monitor_.update(k, result);
    return failure.empty() ? motion_.update(k, record.t_ns, record.p_est) : failure;
  }

 private:
  const RunConfig& config_;
  bool real_measurements_;
  TrackingMonitor monitor_;
  MotionCheck motion_;
};

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
                 const RunSpec& spec, const RunConfig& config, ResultsWriter& writer,
                 RunTrace* trace, RunOutcome* outcome) {
  writer.appendFrame(record);
  trace->t_ns.push_back(frame.t_ns);
  trace->positions.push_back(record.p_est);
  trace->quaternions.push_back(record.q_est);
  if (result.marg_event && result.status.ok() && !result.marg_event->layout.empty()) {
    writeMargEvent(*result.marg_event, k, frame.t_ns, trace->marg_index++, spec, config, writer);
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

// What runWith is given besides the tracks: the resolved spec, the given one's text (root
// attribute run_spec) and the progress callback.
struct RunContext {
  const RunSpec& spec;
  std::string spec_toml;
  const RunProgress& progress;
};

// The TUM trajectory beside the results file, both or neither: a failure to write it removes the
// results file.
void writeTrajectory(const std::string& results_path, const RunTrace& trace) {
  try {
    writeTumTrajectory(tumPathFor(results_path), trace.t_ns, trace.positions, trace.quaternions);
  } catch (const InputError& e) {
    std::error_code ec;
    std::filesystem::remove(results_path, ec);
    throw InputError(e.file(), e.line(),
                     e.detail() + " (the results file " + results_path +
                         " was removed with it: a run leaves both files or neither)");
  }
}

// diagnostics.marg_rounding: one row per marginalization of the window's prior
// (core/estimator/marg_rounding.h), written beside the results file when the run ends.
template <typename Scalar>
struct RoundingRecorder {
  std::vector<MargRoundingRow> rows;
  int frame = 0;  // the frame being processed

  void attach(SlidingWindowEstimator<Scalar>* estimator, const Variant& variant) {
    estimator->setMargObserver([this, variant](const Window<Scalar>& w, const MargPlan& plan,
                                               const MargPrior<Scalar>& before,
                                               const MargPrior<Scalar>& after) {
      MargRoundingRow row;
      row.frame_index = frame;
      // A stage that fails in double (a singular H_μμ) leaves the row's zeros: never the run's.
      measureMargRounding(w, plan, before, after, variant, &row).ok();
      rows.push_back(row);
    });
  }
  void write(const std::string& path) const {
    AtomicFile csv(path);
    csv.write(margRoundingCsv(rows));
    csv.commit();
  }
};

template <typename Scalar>
RunOutcome runWith(const RunContext& context, TrackSource& source) {
  const RunSpec& spec = context.spec;
  const RunConfig& config = spec.config;
  const Sequence& sequence = source.sequence;
  const TrajectoryFunction& trajectory = *source.trajectory;
  RunOutcome outcome;
  outcome.frontend = source.frontend;
  const bool vio = spec.mode == RunMode::kVio;
  outcome.vio = vio;
  outcome.marg_strategy = config.estimator.marg_strategy;
  const SE3<double> T_b_c0 = cameraExtrinsic(sequence.calib.cam0);
  // VIO estimates the body (IMU) frame, VO the left camera: the ATE compares like with like.
  const Trajectory gt_est = vio ? sequence.gt : cameraGroundTruth(sequence.gt, T_b_c0);
  const std::int64_t t0_ns = source.frameTimeNs(0);
  const TrajectorySample first = trajectory.evaluate(t0_ns);
  const SE3<double> T_w_c0_first = SE3<double>(first.R_w_b, first.p_w_b) * T_b_c0;
  std::map<std::string, std::string> imu_provenance;
  std::optional<ImuSetup> imu;
  if (vio) imu = vioImuSetup(spec, sequence, trajectory, t0_ns, &imu_provenance);

  ResultsWriter writer = ResultsWriter::create(
      spec.output,
      runMetadata<Scalar>(spec, source, config, vio, imu_provenance, context.spec_toml));
  RoundingRecorder<Scalar> rounding;  // outlives the estimator that calls it
  SlidingWindowEstimator<Scalar> estimator(config.estimator, spec.variant,
                                           rigFromCalib(sequence.calib), T_w_c0_first,
                                           std::move(imu), config.reporting());
  if (config.diagnostics.marg_rounding) rounding.attach(&estimator, spec.variant);
  const bool predict =
      source.images && config.frontend.prediction == MotionPredictionSource::kEstimator;
  const SE3<double> T_i_c0 = vio ? T_b_c0 : SE3<double>();
  FailureWatch watch(config, source.frontend != "simulated");
  RunTrace trace;
  const int total = static_cast<int>(source.n_frames);
  for (int k = 0; k < total; ++k) {
    ++trace.processed;
    std::optional<FramePrediction> prediction;
    if (predict) prediction = estimatorPrediction(estimator, source.frameTimeNs(k), T_i_c0);
    TrackFrame frame = source.frame(k, prediction ? &*prediction : nullptr);
    if (k == spec.inject_nan_frame && !frame.observations.empty()) {
      frame.observations.front().uv0.x() = std::numeric_limits<double>::quiet_NaN();
    }
    trace.features += static_cast<double>(frame.observations.size());
    const bool dump =
        std::find(spec.dump_windows.begin(), spec.dump_windows.end(), k) != spec.dump_windows.end();
    if (dump) estimator.captureNextWindow();
    rounding.frame = k;
    const FrameResult result = estimator.processFrame(frame);
    if (std::optional<WindowSnapshot> window = estimator.takeCapturedWindow()) {
      writeCapturedWindow(std::move(*window), spec, k);
    }
    FrameRecord record = result;  // the result's /frames row
    if (auto p_gt = interpolatePosition(gt_est, frame.t_ns)) record.p_gt = *p_gt;
    recordFrame(k, frame, result, record, spec, config, writer, &trace, &outcome);
    if (context.progress) context.progress(k + 1, total);

    std::string failure_kind;
    const std::string failure = watch.update(k, result, record, &failure_kind);
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
  outcome.tum_path = tumPathFor(spec.output);
  writeTrajectory(spec.output, trace);
  if (config.diagnostics.marg_rounding) rounding.write(roundingPathFor(spec.output));
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

std::string roundingPathFor(const std::string& results_path) {
  std::string tum = tumPathFor(results_path);
  return tum.substr(0, tum.size() - 4) + ".rounding.csv";
}

RunSpec resolveRunSpec(const RunSpec& spec, const Sequence& sequence, bool has_ground_truth) {
  RunSpec resolved = spec;
  RunConfig& config = resolved.config;
  config.frontend = resolveFrontendOptions(config.frontend, sequence.kind);
  if (config.estimator.min_frames_after_kf < 0)
    config.estimator.min_frames_after_kf = sequence.defaults.min_frames_after_kf;
  if (config.failure.max_position_error_m < 0) {
    config.failure.max_position_error_m = sequence.defaults.max_position_error_m;
  }
  if (resolved.mode == RunMode::kAuto) {
    // Without ground truth there is no initial velocity and gravity direction: VO.
    resolved.mode =
        sequence.kind == DatasetKind::kKitti || !has_ground_truth ? RunMode::kVo : RunMode::kVio;
  }
  return resolved;
}

RunInputs loadRunInputs(const RunSpec& spec) {
  RunInputs inputs;
  inputs.dataset = loadImageSequence(spec.dataset);
  inputs.has_ground_truth = inputs.dataset.sequence.hasTrajectory();
  // --tracks with a --frontend is a usage error (runProblems), decided without reading the file.
  if (!spec.tracks_file.empty() && spec.frontend == FrontendKind::kAuto) {
    inputs.tracks = readTrackFile(spec.tracks_file);
  }
  return inputs;
}

namespace {

// An input check that throws InputError, as a problem of the list.
template <typename Check>
void addInputProblem(std::vector<Problem>* out, Check check) {
  try {
    check();
  } catch (const InputError& e) {
    out->push_back({ProblemKind::kInput, e.file(), e.line(), e.detail()});
  }
}

// Where the tracks come from: one source, one that this dataset can give.
void addTrackSourceProblems(const RunSpec& spec, const RunInputs& inputs,
                            std::vector<Problem>* out) {
  const Sequence& sequence = inputs.dataset.sequence;
  if (!spec.tracks_file.empty() && spec.frontend != FrontendKind::kAuto) {
    out->push_back({ProblemKind::kUsage, "", 0,
                    fmt::format("--tracks FILE and --frontend {} both say where the tracks come "
                                "from: give one of them",
                                nameOf(kFrontendKindNames, spec.frontend))});
  }
  if (inputs.tracks && !spec.tracks_any_sequence) {
    addInputProblem(out, [&] { checkTracksBelongTo(*inputs.tracks, spec.tracks_file, sequence); });
  }
  if (!spec.tracks_file.empty()) return;
  const bool images = inputs.dataset.images.has_value();
  if (spec.frontend == FrontendKind::kImages && !images) {
    out->push_back({ProblemKind::kInput, sequence.directory, 0,
                    "--frontend images: the sequence has no images (expected mav0/cam0/data/ or "
                    "image_0/ and image_1/)"});
  }
  const bool simulate = spec.frontend == FrontendKind::kSimulated ||
                        (spec.frontend == FrontendKind::kAuto && !images);
  if (simulate && !inputs.has_ground_truth) {
    out->push_back({ProblemKind::kInput, sequence.directory, 0,
                    fmt::format("sequence {} has no trajectory to simulate from (only camera "
                                "timestamps); use its images (--frontend images) or a track file",
                                sequence.name)});
  }
}

// --dump-windows: frames the run reaches, a strategy whose windows can be captured, a folder that
// can be created (probed: created and removed again when it does not exist yet).
void addCaptureProblems(const RunSpec& spec, const Sequence& sequence, std::vector<Problem>* out) {
  if (spec.dump_windows.empty()) return;
  const auto usage = [out](std::string message) {
    out->push_back({ProblemKind::kUsage, "", 0, std::move(message)});
  };
  // A window the run can never reach would be captured silently never.
  const int frames =
      spec.max_frames > 0 ? spec.max_frames : static_cast<int>(sequence.cam_t_ns.size());
  for (const int frame : spec.dump_windows) {
    if (frame >= frames) {
      usage(fmt::format("--dump-windows {}: the run has {} frames ({}), expected indices below",
                        frame, frames, spec.max_frames > 0 ? "--frames" : sequence.name));
    }
  }
  // A captured window holds hosted landmarks and a prior over frame states only.
  if (spec.config.estimator.marg_strategy != MargStrategy::kDiscard) {
    usage("window capture (--dump-windows) needs marginalization strategy discard");
  }
  std::error_code ec;
  const std::filesystem::path dir(spec.dump_dir);
  if (std::filesystem::is_directory(dir, ec)) return;
  if (!std::filesystem::create_directories(dir, ec) || ec) {
    usage(fmt::format("--dump-dir {}: cannot create the folder ({})", spec.dump_dir,
                      ec ? ec.message() : "it exists and is not a folder"));
    return;
  }
  std::filesystem::remove(dir, ec);
}

// What needs VIO, on a VO run: a problem of the options (usage, exit 2) where the user chose VO
// on a dataset that can run VIO, else a problem of the dataset (input, exit 1, naming its folder),
// so that one relation always exits the same way.
void addNeedsVioProblem(const RunInputs& inputs, std::string message, std::vector<Problem>* out) {
  const Sequence& sequence = inputs.dataset.sequence;
  const bool dataset_can_vio = inputs.has_ground_truth && sequence.kind != DatasetKind::kKitti;
  if (dataset_can_vio) {
    out->push_back({ProblemKind::kUsage, "", 0, message + " (this run is --mode vo)"});
  } else {
    out->push_back({ProblemKind::kInput, sequence.directory, 0,
                    fmt::format("{}: sequence {} runs VO only ({})", message, sequence.name,
                                inputs.has_ground_truth ? "KITTI odometry has no IMU"
                                                        : "it has no ground truth")});
  }
}

// The mode against the dataset: VIO needs ground truth and an IMU; a real IMU, another IMU noise
// profile and a marginalization strategy other than discard need VIO.
void addModeProblems(const RunSpec& spec, const RunInputs& inputs, std::vector<Problem>* out) {
  const Sequence& sequence = inputs.dataset.sequence;
  const bool vio = spec.mode == RunMode::kVio;
  if (vio && !inputs.has_ground_truth) {
    out->push_back({ProblemKind::kInput, sequence.directory, 0,
                    "VIO starts from the ground-truth state at its first frame, and this sequence "
                    "has no ground truth (use --mode vo)"});
  }
  if (vio && sequence.kind == DatasetKind::kKitti) {
    out->push_back({ProblemKind::kInput, sequence.directory, 0,
                    "KITTI odometry has no IMU: VIO needs EuRoC or TUM-VI (use --mode vo)"});
  }
  if (spec.imu == ImuSource::kReal && !vio) {
    addNeedsVioProblem(inputs, "--imu real needs VIO", out);
  } else if (spec.imu == ImuSource::kReal && !sequence.imu) {
    out->push_back({ProblemKind::kInput, sequence.directory, 0,
                    fmt::format("--imu real: sequence {} has no real IMU recording (expected "
                                "mav0/imu0/data.csv; use the synthetic IMU)",
                                sequence.name)});
  } else if (spec.imu == ImuSource::kReal) {
    addInputProblem(out, [&] { checkImuCoverage(sequence); });
  }
  if (vio) return;
  const EstimatorSettings& estimator = spec.config.estimator;
  if (estimator.marg_strategy != MargStrategy::kDiscard) {
    addNeedsVioProblem(inputs,
                       fmt::format("marginalization strategy {} needs VIO (EuRoC or TUM-VI)",
                                   toString(estimator.marg_strategy)),
                       out);
  }
  // A VO run has no IMU: another profile would be recorded in its config and used nowhere.
  if (estimator.imu_noise_profile != EstimatorSettings().imu_noise_profile) {
    const std::string key = "imu.noise_profile";
    const Problem where =
        spec.config.located({key, fmt::format("{} = {} weighs IMU factors, which only VIO has", key,
                                              toString(estimator.imu_noise_profile))});
    addNeedsVioProblem(inputs,
                       where.line > 0
                           ? fmt::format("{}:{}: {}", where.file, where.line, where.message)
                           : where.message,
                       out);
  }
}

}  // namespace

std::vector<Problem> runProblems(const RunSpec& spec, const RunInputs& inputs) {
  std::vector<Problem> out = spec.config.locatedProblems();
  addTrackSourceProblems(spec, inputs, &out);
  addModeProblems(spec, inputs, &out);
  // The config's alias of the psd axis `c` (core/estimator/variant.h) would do nothing or clash.
  const std::string psd = psdHessianPriorProblem(spec.variant);
  if (spec.config.estimator.psd_hessian_prior && !psd.empty()) {
    out.push_back(spec.config.located(
        {"marginalization.psd_hessian_prior",
         fmt::format("marginalization.psd_hessian_prior = true with variant {}: {}",
                     spec.variant.name(), psd)}));
  }
  addCaptureProblems(spec, inputs.dataset.sequence, &out);
  // A window file (window_io.h) has no field for the stereo offset: its replay would differ.
  if (spec.config.estimator.estimate_right_cx_offset && !spec.dump_windows.empty()) {
    out.push_back(spec.config.located(
        {"estimator.estimate_right_cx_offset",
         "estimator.estimate_right_cx_offset = true with window capture (dump_windows): a window "
         "file does not record the stereo offset; capture without it"}));
  }
  const PriorStorage& storage = spec.variant.storage;
  const bool plain_sq = spec.variant.marg == MargMethod::kSchur && hessianStorage(storage) &&
                        storage.preconditioning == Preconditioning::kNone &&
                        storage.psd == PsdProjection::kNone &&
                        !spec.config.estimator.psd_hessian_prior;
  if (spec.config.diagnostics.marg_rounding && (!plain_sq || spec.mode != RunMode::kVo)) {
    out.push_back(spec.config.located(
        {"diagnostics.marg_rounding",
         fmt::format("diagnostics.marg_rounding = true with variant {} ({}): it measures a VO "
                     "run's Schur marginalization of a plain Hessian prior (sc-sq)",
                     spec.variant.name(), nameOf(kRunModeNames, spec.mode))}));
  }
  return out;
}

PreparedRun prepareRun(const RunSpec& spec) {
  PreparedRun run{spec, spec, loadRunInputs(spec)};
  const Sequence& sequence = run.inputs.dataset.sequence;
  run.resolved = resolveRunSpec(spec, sequence, run.inputs.has_ground_truth);
  const std::vector<Problem> problems = runProblems(run.resolved, run.inputs);
  if (!problems.empty()) throwProblems(problems);
  return run;
}

RunOutcome runPrepared(PreparedRun run, const RunProgress& progress) {
  applyCalibration(run.resolved.config.calibration, &run.inputs.dataset.sequence.calib);
  TrackSource source = obtainTracks(trackSourceOptions(run.resolved), run.inputs.dataset,
                                    std::move(run.inputs.tracks));
  const RunContext context{run.resolved, run.given.toToml(), progress};
  if (run.resolved.variant.floatState()) return runWith<float>(context, source);
  return runWith<double>(context, source);
}

RunOutcome runSequence(const RunSpec& spec, const RunProgress& progress) {
  return runPrepared(prepareRun(spec), progress);
}

}  // namespace marglab
