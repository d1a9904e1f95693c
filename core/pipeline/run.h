#pragma once
// One run of the harness: a real sequence (its ground truth drives the simulated stereo tracks),
// one variant, one seed → one HDF5 results file (docs/design.md §6) and its TUM trajectory.
//
//   sequence → TrajectorySpline → world + simulated tracks (seeded) → VoEstimator<Scalar>
//            → per frame: FrameRecord; per marginalization: diagnostics of the shadow prior
//            → ResultsWriter::finish (ATE after SE(3) alignment) → atomic rename.
//
// The state is the left camera T_w_c0 (docs/design.md §3, VO); it starts at the true first camera
// pose (the same for every variant), and the ATE compares camera positions with the ground truth
// expressed for cam0 (T_w_b T_b_c0). A run fails — status "failed" in the file, never a crash or
// a missing file — when the estimator reports a numerical failure (non-finite cost or state,
// repeated solve failure) or the position error exceeds the dataset's bound (failure_kind
// "numerical"), or when it has lost the scene (failure_kind "tracking", tracking_monitor.h: no
// ground truth involved).
//
// Images (frontend "images"): each frame is tracked just before the estimator processes it, and
// with [frontend] prediction = "estimator" the front-end starts from the estimator's prediction
// of that frame (its predicted pose, its landmarks; core/frontend/motion_prediction.h).

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/data/types.h"
#include "core/estimator/variant.h"
#include "core/estimator/window.h"
#include "core/frontend/track_source.h"
#include "core/geometry/camera.h"
#include "core/io/results_file.h"
#include "core/pipeline/run_config.h"
#include "core/pipeline/run_spec.h"
#include "core/sim/trajectory_spline.h"

namespace marglab {

struct RunOutcome {
  RunStatus status = RunStatus::kOk;
  bool vio = false;  // the mode that ran
  MargStrategy marg_strategy = MargStrategy::kDiscard;
  std::int64_t failure_frame = -1;
  std::string failure_reason;
  std::string failure_kind;  // "numerical" | "tracking" (tracking_monitor.h); "" when ok
  SummaryValues summary;
  std::string tum_path;
  double mean_features_per_frame = 0;
  std::string frontend;                // "images" | "simulated" | "tracks"
  std::string frontend_summary;        // one line: features, tracked, stereo share, speed
  std::int64_t n_keyframe_events = 0;  // /sparsify rows (strategies dense, nfr)
};

// A run's dataset, loaded once — the sequence (calibration, timestamps, ground truth, IMU), its
// images if the folder has them, and the track file's tracks for a run on one — before anything is
// simulated, tracked or estimated.
struct RunInputs {
  ImageSequence dataset;
  bool has_ground_truth = false;
  std::optional<TrackStream> tracks;  // spec.tracks_file, read (not with a --frontend)
};

// Throws InputError: a dataset that does not load, a track file that cannot be read. A track file
// given with a --frontend is not read: runProblems reports the pair as a usage error.
RunInputs loadRunInputs(const RunSpec& spec);

// Every problem of a resolved spec (IsValid-style; empty: valid), in one list — the only place a
// run's validity is decided (`marglab run`, `marglab sweep` at plan time, runSequence): the
// config's ranges and relations (RunConfig::locatedProblems) and the relations between the
// spec and its inputs — --tracks with --frontend, a track file of this sequence (unless
// tracks_any_sequence), images for frontend images, a trajectory to simulate from, --dump-windows
// within the run's frames and only with strategy discard, a dump folder that can be created, VIO
// only with ground truth and not on KITTI, --imu real only with VIO and a real IMU covering the
// frames, strategies other than discard only with VIO, marginalization.psd_hessian_prior only
// with a Hessian prior storage.
std::vector<Problem> runProblems(const RunSpec& spec, const RunInputs& inputs);

// The spec with what depends on the sequence filled in — mode auto → vo | vio, the config's
// dataset defaults (keyframe spacing, position bound, front-end settings); not validated.
RunSpec resolveRunSpec(const RunSpec& spec, const Sequence& sequence, bool has_ground_truth);

// A run ready to start: its inputs loaded, its spec resolved and valid.
struct PreparedRun {
  RunSpec given;     // as given (recorded in the results file: run_spec)
  RunSpec resolved;  // resolveRunSpec(given)
  RunInputs inputs;
};

// load → resolve → validate: every problem of runProblems in one error (throwProblems:
// UsageError or InputError), before any work.
PreparedRun prepareRun(const RunSpec& spec);

// Called after each frame with (frames done, total frames).
using RunProgress = std::function<void(int, int)>;

// Obtains the tracks and runs a prepared run. Numerical failure is a result (status failed), not
// an exception. A run leaves its results file and its TUM trajectory, both or neither: an
// InputError writing the trajectory removes the results file (the message says so).
RunOutcome runPrepared(PreparedRun run, const RunProgress& progress = {});

// prepareRun, then runPrepared.
RunOutcome runSequence(const RunSpec& spec, const RunProgress& progress = {});

// The IMU stream and first state of a VIO run, and what they are (provenance: root attributes
// imu, initial_biases, initial_state, imu_noise). `spec` is resolved (resolveRunSpec).
// The densities are those of spec.config.estimator.imu_noise_profile, for the synthetic IMU and the
// estimator's weights alike. The first state is the ground truth at t0_ns (pose and velocity from
// the trajectory) with zero biases, or the recorded ground-truth biases for the real IMU where the
// sequence has them — the same for every variant. Throws InputError (a profile without calibration,
// too few real samples).
ImuSetup vioImuSetup(const RunSpec& spec, const Sequence& sequence,
                     const TrajectoryFunction& trajectory, std::int64_t t0_ns,
                     std::map<std::string, std::string>* provenance);

// The estimator's rig from a calibration: pinhole intrinsics (images are undistorted) and the
// body-to-camera extrinsics T_i_c0, T_i_c1.
StereoRig<double> rigFromCalib(const StereoCalib& calib);

// The TUM path written next to a results file.
std::string tumPathFor(const std::string& results_path);
// The marginalization rounding CSV (diagnostics.marg_rounding) next to a results file.
std::string roundingPathFor(const std::string& results_path);

// The file name of a captured window: "euroc-MH_01_easy_ns-qr-sqrt-f32_000060.win.gz".
std::string windowFileName(const std::string& dataset, const std::string& variant, int frame);

}  // namespace marglab
