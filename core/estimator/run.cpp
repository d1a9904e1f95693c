#include "core/estimator/run.h"

#include <fmt/core.h>

#include <chrono>
#include <cmath>
#include <limits>

#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/diagnostics/ate.h"
#include "core/diagnostics/diagnostics.h"
#include "core/estimator/vo_estimator.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/trajectory_spline.h"

namespace marglab {
namespace {

SE3<double> cameraExtrinsic(const CameraCalib& camera) {
  return SE3<double>(camera.R_b_c, camera.t_b_c);
}

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

template <typename Scalar>
RunOutcome runWith(const RunOptions& options, const Sequence& sequence, const TrackStream& stream,
                   const TrajectoryFunction& trajectory, const EstimatorConfig& config) {
  RunOutcome outcome;
  const SE3<double> T_b_c0 = cameraExtrinsic(sequence.calib.cam0);
  const Trajectory gt_cam = cameraGroundTruth(sequence.gt, T_b_c0);
  const TrajectorySample first = trajectory.evaluate(stream.frames.front().t_ns);
  const SE3<double> T_w_c0_first = SE3<double>(first.R_w_b, first.p_w_b) * T_b_c0;

  RunMetadata metadata;
  metadata.dataset = splitDataset(sequence);
  const std::string& name = sequence.name;
  metadata.sequence = name.substr(name.find('/') == std::string::npos ? 0 : name.find('/') + 1);
  metadata.variant = options.variant.name();
  metadata.precision = options.variant.precision == Precision::kF32 ? "f32" : "f64";
  metadata.mode = "vo";
  metadata.seed = options.seed;
  metadata.config_toml = config.toToml();
  if (options.variant.marg == MargMethod::kQr) {
    metadata.qr_threshold_mode = toString(config.qr_threshold_mode);
    metadata.qr_threshold = config.qr_threshold >= 0
                                ? config.qr_threshold
                                : static_cast<double>(NumericTraits<Scalar>::sqrtEpsilon());
  }
  metadata.extra = {{"dataset_path", sequence.directory},
                    {"gt_source", sequence.gt_source},
                    {"measurements", "simulated stereo tracks, undistorted pinhole"}};
  ResultsWriter writer = ResultsWriter::create(options.output, metadata);

  VoEstimator<Scalar> estimator(config, options.variant, rigFromCalib(sequence.calib),
                                T_w_c0_first);
  std::vector<std::int64_t> t_ns;
  std::vector<Eigen::Vector3d> positions;
  std::vector<Eigen::Quaterniond> quaternions;
  const int total = static_cast<int>(stream.frames.size());
  std::int64_t marg_index = 0;
  double features = 0;
  int processed = 0;
  for (int k = 0; k < total; ++k) {
    ++processed;
    TrackFrame frame = stream.frames[k];
    if (k == options.inject_nan_frame && !frame.observations.empty()) {
      frame.observations.front().uv0.x() = std::numeric_limits<double>::quiet_NaN();
    }
    features += static_cast<double>(frame.observations.size());
    const FrameResult result = estimator.processFrame(frame);

    FrameRecord record;
    record.t_ns = frame.t_ns;
    record.is_keyframe = result.is_keyframe;
    record.n_landmarks = result.n_landmarks;
    record.n_observations = result.n_observations;
    record.lm_iterations = result.lm_iterations;
    record.cost_initial = result.cost_initial;
    record.cost_final = result.cost_final;
    record.t_opt_s = result.t_opt_s;
    record.t_marg_s = result.t_marg_s;
    record.p_est = result.T_w_c.translation();
    record.q_est = result.T_w_c.unitQuaternion();
    if (auto p_gt = interpolatePosition(gt_cam, frame.t_ns)) record.p_gt = *p_gt;
    writer.appendFrame(record);
    t_ns.push_back(frame.t_ns);
    positions.push_back(record.p_est);
    quaternions.push_back(record.q_est);

    if (result.marg_event && result.status.ok() && !result.marg_event->frame_ids.empty()) {
      const MargEvent& event = *result.marg_event;
      PriorLayout layout;
      GaugeState state;
      for (size_t i = 0; i < event.frame_ids.size(); ++i) {
        layout.push_back({PriorVariableKind::kPose, event.frame_ids[i], static_cast<int>(6 * i)});
        state.T_w_i[event.frame_ids[i]] = event.T_w_c[i];
      }
      const std::uint64_t seed = config.diagnostics_seed + static_cast<std::uint64_t>(marg_index);
      const bool sqrt_storage = options.variant.storage == PriorStorage::kSqrt;
      const PriorDiagnostics diagnostics =
          sqrt_storage ? diagnoseSqrtPrior(event.J_m, event.r_m, layout, state, seed)
                       : diagnosePrior(event.H_m, event.b_m, layout, state, seed);
      writer.appendMarg(makeMargRecord(k, frame.t_ns, event.prior_rows, diagnostics));
      if (config.store_prior_every > 0 && marg_index % config.store_prior_every == 0) {
        writer.appendPriorMatrices(marg_index, layout, event.H_m, event.b_m,
                                   sqrt_storage ? &event.J_m : nullptr,
                                   sqrt_storage ? &event.r_m : nullptr);
      }
      ++marg_index;
    }
    if (options.progress) options.progress(k + 1, total);

    std::string failure;
    if (!result.status.ok()) {
      failure = result.status.toString();
    } else if (std::isfinite(record.p_gt.x()) &&
               (record.p_est - record.p_gt).norm() > config.max_position_error_m) {
      failure = fmt::format("position error {:.2f} m exceeds the bound of {:.1f} m",
                            (record.p_est - record.p_gt).norm(), config.max_position_error_m);
    }
    if (!failure.empty()) {
      outcome.status = RunStatus::kFailed;
      outcome.failure_frame = k;
      outcome.failure_reason = failure;
      break;
    }
  }
  outcome.mean_features_per_frame = processed > 0 ? features / processed : 0;
  outcome.summary =
      writer.finish(RunSummary{}, outcome.status, outcome.failure_frame, outcome.failure_reason);
  outcome.tum_path = tumPathFor(options.output);
  writeTumTrajectory(outcome.tum_path, t_ns, positions, quaternions);
  return outcome;
}

}  // namespace

std::string tumPathFor(const std::string& results_path) {
  const std::string suffix = ".h5";
  std::string base = results_path;
  if (base.size() > suffix.size() &&
      base.compare(base.size() - suffix.size(), suffix.size(), suffix) == 0) {
    base.resize(base.size() - suffix.size());
  }
  return base + ".tum";
}

RunOutcome runSequence(const RunOptions& options) {
  const Sequence sequence = loadSequence(options.dataset);
  if (!sequence.hasTrajectory()) {
    throw InputError(sequence.directory, 0,
                     fmt::format("sequence {} has no trajectory to simulate from (only camera "
                                 "timestamps are shipped)",
                                 sequence.name));
  }
  EstimatorConfig config = options.config;
  if (config.min_frames_after_kf < 0)
    config.min_frames_after_kf = sequence.defaults.min_frames_after_kf;
  if (config.max_position_error_m < 0) {
    config.max_position_error_m = sequence.defaults.max_position_error_m;
  }
  const TrajectorySpline spline = TrajectorySpline::fromSequence(sequence);
  SimulationOptions simulation = defaultSimulationOptions(sequence, options.seed);
  if (options.max_frames > 0) simulation.tracker.max_frames = options.max_frames;
  const TrackStream stream = simulateSequence(sequence, spline, simulation);
  if (stream.frames.empty()) {
    throw InputError(sequence.directory, 0, "no camera frame lies inside the trajectory");
  }
  if (options.variant.precision == Precision::kF32) {
    return runWith<float>(options, sequence, stream, spline, config);
  }
  return runWith<double>(options, sequence, stream, spline, config);
}

}  // namespace marglab
