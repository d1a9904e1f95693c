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
#include <string>
#include <vector>

#include "core/data/types.h"
#include "core/estimator/config.h"
#include "core/estimator/variant.h"
#include "core/estimator/window.h"
#include "core/frontend/track_source.h"
#include "core/geometry/camera.h"
#include "core/io/results_file.h"
#include "core/sim/trajectory_spline.h"

namespace marglab {

// VO: stereo only (the state is the left camera). VIO: stereo + IMU (the state is the body).
// kAuto: VIO where the dataset has an IMU (EuRoC, TUM-VI), VO on KITTI.
enum class RunMode { kAuto, kVo, kVio };
// The IMU of a VIO run: synthesized from the spline (default), or the sequence's recording.
enum class ImuSource { kSynthetic, kReal };

// Everything a run is given: dataset, variant, config (defaults < --config FILE < options, each
// key's origin recorded) and the command line's other choices. runSequence resolves it once
// against the sequence (resolveRunOptions) and validates it once (runProblems); every step after
// that reads the resolved options only.
struct RunOptions {
  std::string dataset;  // "kitti/10", "euroc/MH_01_easy", or a folder in original layout
  Variant variant;
  RunMode mode = RunMode::kAuto;
  ImuSource imu = ImuSource::kSynthetic;
  // Where the tracks come from (core/frontend/track_source.h): a track file when tracks_file is
  // set, else the images or the simulation (auto: images where the folder has them).
  FrontendKind frontend = FrontendKind::kAuto;
  std::string tracks_file;
  int max_frames = 0;  // 0: the whole sequence
  std::uint64_t seed = 1;
  EstimatorConfig config;
  std::string output;  // results file (.h5); the TUM trajectory goes to <output minus .h5>.tum
  // Fault injection for tests of the failure path: a NaN in the first measurement of this frame.
  int inject_nan_frame = -1;
  // Window capture: the windows of these frame indices (0-based, before their optimization, with
  // the step taken) are written to dump_dir as <dataset>_<variant>_<frame>.win.gz
  // (core/estimator/window_io.h).
  std::vector<int> dump_windows;
  std::string dump_dir;
  // Called after each frame with (frames done, total frames).
  std::function<void(int, int)> progress;
};

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

// Every problem of resolved options (IsValid-style; empty: valid), in one list: the config's
// ranges and relations (EstimatorConfig::locatedProblems) and the relations between the options
// and with the sequence — --tracks with --frontend, --dump-windows within the run's frames and
// only with strategy discard, VIO only with ground truth and not on KITTI, --imu real and
// strategies other than discard only with VIO, marginalization.psd_hessian_prior only with a
// Hessian prior storage.
std::vector<Problem> runProblems(const RunOptions& options, const Sequence& sequence,
                                 bool has_ground_truth);

// The options with what depends on the sequence filled in — mode auto → vo | vio, the config's
// dataset defaults (keyframe spacing, position bound, front-end settings) — then validated: every
// problem of runProblems in one error (throwProblems: UsageError or InputError).
RunOptions resolveRunOptions(const RunOptions& options, const Sequence& sequence,
                             bool has_ground_truth);

// Obtains the tracks, resolves and validates the options (resolveRunOptions) and runs. Throws
// InputError for bad input (unknown dataset, sequence without trajectory, unwritable output) and
// UsageError / InputError for invalid options; numerical failure is a result (status failed), not
// an exception.
RunOutcome runSequence(const RunOptions& options);

// The IMU stream and first state of a VIO run, and what they are (provenance: root attributes
// imu, initial_biases, initial_state, imu_noise). `options` are resolved (resolveRunOptions).
// The densities are those of options.config.imu_noise_profile, for the synthetic IMU and the
// estimator's weights alike. The first state is the ground truth at t0_ns (pose and velocity from
// the trajectory) with zero biases, or the recorded ground-truth biases for the real IMU where the
// sequence has them — the same for every variant. Throws InputError (a profile without calibration,
// too few real samples).
ImuSetup vioImuSetup(const RunOptions& options, const Sequence& sequence,
                     const TrajectoryFunction& trajectory, std::int64_t t0_ns,
                     std::map<std::string, std::string>* provenance);

// The estimator's rig from a calibration: pinhole intrinsics (images are undistorted) and the
// body-to-camera extrinsics T_i_c0, T_i_c1.
StereoRig<double> rigFromCalib(const StereoCalib& calib);

// The TUM path written next to a results file.
std::string tumPathFor(const std::string& results_path);

// The file name of a captured window: "euroc-MH_01_easy_ns-qr-sqrt-f32_000060.win.gz".
std::string windowFileName(const std::string& dataset, const std::string& variant, int frame);

}  // namespace marglab
