#pragma once
// The disparity of a rectified stereo pair measured against motion stereo (`marglab datasets
// stereo-bias`; the method of tools/scripts/stereo_bias.py, results/real_kitti06/README.md §1).
//
// Why. A stereo VO takes its metric scale from its stereo depths z = f b / d: a disparity error δ
// (d_measured = d_true + δ) scales every depth by d_true / (d_true + δ), and the trajectory with
// it. The stereo pairs alone cannot see δ. Motion stereo can: ground-truth poses T_w_c of the left
// camera give baselines of metres between the frames of one left-camera track, independent of
// the stereo baseline b and of the right camera.
//
//   1. A left track observed in ≥ min_frames frames whose camera centres span ≥ min_motion_m is
//      triangulated from its left pixels u_k alone (triangulateFromMotion): X_w minimizing
//      Σ_k ‖π(T_c_w,k X_w) − u_k‖²; linear start (per view the two rows (r1 − x r3) X = x t3 − t1,
//      (r2 − y r3) X = y t3 − t2 of the bearing constraint), then Gauss–Newton with
//      J_k = ∂π/∂p · R_c_w,k. Tracks with an RMS residual above max_rms_px are dropped.
//   2. For each of its observations with a right match: z_k = depth of X_w in frame k, the motion
//      disparity d_motion = f b / z_k and its standard deviation σ = ‖∂d/∂X‖ under
//      Σ_X = (JᵀJ)⁻¹ · max(rms, min_noise_px)², with ∂d/∂X = −(f b / z²) r3,k; kept when
//      σ ≤ max_sigma_px.
//   3. e = d_stereo − d_motion, with d_stereo = (u0 − u1) − (cx0 − cx1): the disparity the
//      estimator's camera model explains as f b / z (cx0 = cx1 in KITTI's calib.txt; a
//      [calibration] right_cx_shift_px moves cx1, core/pipeline/run_config.h).
// The offset is δ = median e (robust; the estimator's depths inherit it whole; against poses
// that are not ground truth the fit's intercept c, OffsetStatistic below); its correction is
// right_cx_shift_px += −δ. Beside it: the spread (1.4826 · MAD), the s.e. of the mean, a weighted
// fit e = c + s · d_motion (w = 1 / (σ² + min_noise²); c an additive offset, s a relative baseline
// error b_true = b (1 + s)), e by depth, column and row, and the vertical misalignment v1 − v0 of
// every stereo match of the frames (no ground truth needed) over a 6 × 6 grid of the image.
// Held out: the frames split in two halves, δ of each applied to the other (the residual median).
//
// The result depends on the ground truth's scale and on f only through the pixel angles (motion
// depth ∝ f at fixed pixels, so f cancels in f b / z): it measures the disparities against b.

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

#include "core/data/tracks.h"
#include "core/frontend/frontend_options.h"
#include "core/frontend/image_folder.h"
#include "core/geometry/camera.h"
#include "core/geometry/se3.h"

namespace marglab {

template <typename Scalar>
struct MotionTriangulation {
  Eigen::Matrix<Scalar, 3, 1> p_w;
  Scalar rms_px = 0;                        // RMS of the 2n reprojection residuals
  Eigen::Matrix<Scalar, 3, 3> cov_per_px2;  // (JᵀJ)⁻¹: Σ_X per px² of pixel noise
};

// X_w from the left pixels uv[k] seen from poses T_c_w[k] (step 1 above, `iterations` Gauss–Newton
// steps at most); nullopt when a point falls behind a camera (depth ≤ cam.min_depth) or JᵀJ is
// singular to working precision (its condition number above 1 / (100 ε)).
template <typename Scalar>
std::optional<MotionTriangulation<Scalar>> triangulateFromMotion(
    const std::vector<SE3<Scalar>>& T_c_w, const std::vector<Eigen::Matrix<Scalar, 2, 1>>& uv,
    const PinholeCamera<Scalar>& cam, int iterations = 10);

struct MotionStereoSettings {
  int min_frames = 4;          // observations of a track
  double min_motion_m = 2.0;   // camera travel within a track
  double max_rms_px = 0.5;     // left reprojection RMS of a triangulated track
  double max_sigma_px = 0.15;  // σ of f b / z_motion above which an observation is dropped
  double min_noise_px = 0.05;  // pixel noise floor for the covariance and the weights
};

// The rectified pair as the measurement sees it.
struct RectifiedStereo {
  double f = 0, cx0 = 0, cx1 = 0, cy = 0, baseline_m = 0;
};

struct DisparitySample {
  int frame = 0;
  double u0 = 0, v0 = 0;
  double d_stereo = 0;  // (u0 − u1) − (cx0 − cx1)
  double d_motion = 0;  // f b / z_motion
  double sigma = 0;     // σ of d_motion
  double z = 0;         // depth from motion [m]
  double dv = 0;        // v1 − v0
  double error() const { return d_stereo - d_motion; }
};

// Steps 1–3 over the observations of frames [first, last] of `stream` (frame k of the stream at
// pose T_w_c[k], the left camera); `tracks_used` gets the number of tracks triangulated.
std::vector<DisparitySample> motionStereoSamples(const TrackStream& stream,
                                                 const std::vector<SE3<double>>& T_w_c,
                                                 const RectifiedStereo& stereo, int first, int last,
                                                 const MotionStereoSettings& settings,
                                                 int* tracks_used = nullptr);

struct ErrorBin {
  double lo = 0, hi = 0;
  int n = 0;
  double mean = 0, median = 0, se = 0;
  double rel_depth_error = 0;  // median of −e / d_stereo (the depths' relative error)
  double dv = 0;               // median v1 − v0
};

struct DisparityErrorSummary {
  int n = 0;
  double median = 0, mean = 0, se = 0, spread = 0;  // spread: 1.4826 · MAD
  double fit_c = 0, fit_c_se = 0, fit_s = 0, fit_s_se = 0;
  double rel_depth_error = 0;  // median −e / d_stereo
  double dv = 0;               // median v1 − v0 of the samples
  std::vector<ErrorBin> by_depth, by_column, by_row;
};

// Weighted least squares e = c + s · d_motion (w = 1 / (σ² + min_noise²)), the standard errors
// from the residuals' scatter.
struct OffsetScaleFit {
  double c = 0, s = 0, c_se = 0, s_se = 0;
};
OffsetScaleFit fitOffsetScale(const std::vector<DisparitySample>& samples, double min_noise_px);

// Summary of `samples` (at least 3); bins with fewer than 5 samples are left out.
DisparityErrorSummary summarizeDisparityErrors(const std::vector<DisparitySample>& samples,
                                               double min_noise_px, int width, int height);

// Median v1 − v0 of the stereo matches of frames [first, last] in a rows × cols grid of the image
// (NaN where a cell has fewer than 5 matches), row-major; the edges are round(i · size / 6).
struct VerticalField {
  std::vector<int> row_edges, column_edges;
  std::vector<double> median_dv;  // (row_edges.size() − 1) × (column_edges.size() − 1)
  int n = 0;
  double overall = 0;  // median over every match
};
VerticalField verticalMisalignment(const TrackStream& stream, int first, int last, int width,
                                   int height);

// The offset statistic (OffsetStatistic below) of one half of the frames, applied to the other.
struct HeldOutCheck {
  int measure_first = 0, measure_last = 0, test_first = 0, test_last = 0;
  int n_measure = 0, n_test = 0;
  double offset = 0;       // the statistic on the measured frames
  double test_before = 0;  // the statistic on the test frames, as given
  double test_after = 0;   // the same after the correction: test_before − offset
};

// Which statistic is the offset: with ground-truth poses the median e (what the estimator's
// depths inherit whole); with poses that are not ground truth (--poses, e.g. a run's own
// estimate, whose scale comes from the biased disparities) the fit's intercept c: an additive
// offset that a scale λ of the trajectory cannot absorb (λ moves d_motion to d / λ, i.e. into
// s) — whether the offset is observable without ground truth.
enum class OffsetStatistic { kMedian, kFitIntercept };

struct StereoBiasStudy {
  std::string dataset, sequence;
  std::string poses;  // where the poses came from
  OffsetStatistic statistic = OffsetStatistic::kMedian;
  int first = 0, last = 0;  // frames measured
  RectifiedStereo stereo;
  double config_shift_px = 0;  // [calibration] right_cx_shift_px the front-end tracked with
  MotionStereoSettings settings;
  int tracks = 0, tracks_used = 0;
  DisparityErrorSummary summary;
  VerticalField vertical;
  std::vector<HeldOutCheck> held_out;  // each half measured, the other tested (both ways)
  int width = 0, height = 0;
  // The measured offset (the statistic) and the correction: the config's shift minus it.
  double offset() const {
    return statistic == OffsetStatistic::kMedian ? summary.median : summary.fit_c;
  }
  double correctedShift() const { return config_shift_px - offset(); }
};

// What measureStereoBias measures: frames [first, last] of the folder, tracked with `frontend`
// on the folder's calibration with `config_shift_px` already applied; poses from the ground truth
// or, when `poses` is set, from that trajectory of the left camera (TUM file `poses_file`).
struct StereoBiasRequest {
  std::string dataset;
  FrontendOptions frontend;
  double config_shift_px = 0;
  int first = 0, last = 0;
  std::optional<Trajectory> poses;
  std::string poses_file;
  MotionStereoSettings settings;
};

// The frames [first, last] of a KITTI-layout folder: tracked by the image front-end (frames
// 0..last, `frontend` resolved for KITTI) on `images.sequence.calib`, then measured against the
// poses. Throws InputError naming the folder (or the poses file) for a folder that is not KITTI's
// rectified layout, no poses (no ground truth and no --poses), a measured frame without a pose
// (within 1 ms of its time), frames out of range or fewer than 2 · min_frames of them, or fewer
// than 10 usable observations.
StereoBiasStudy measureStereoBias(const ImageSequence& images, const StereoBiasRequest& request);

// The report (lines of text, for stdout) and the config fragment: the report as TOML comments,
// then [calibration] right_cx_shift_px = correctedShift() (`marglab run --config` reads it).
std::string stereoBiasReport(const StereoBiasStudy& study);
std::string stereoBiasToml(const StereoBiasStudy& study, const std::string& command_line);

}  // namespace marglab
