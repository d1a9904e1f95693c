#pragma once
// The settings of the stereo optical-flow front-end (optical_flow.h), config section [frontend]
// (core/pipeline/run_config.h binds and validates them with the other keys; docs/design.md §9).
//
// Keys whose best value depends on the dataset's resolution and motion have a sentinel (−1, or an
// empty list) that resolveFrontendOptions() replaces by the dataset's default:
//   grid_cell_px       EuRoC / TUM-VI 50 (752×480, 512×512), KITTI 30 (1226×370: wide and low,
//                      Basalt's KITTI grid);
//   pyramid_levels     EuRoC / TUM-VI 3, KITTI 4 (10 Hz driving: features near the border and on
//                      the road move tens of pixels per frame; a 4th level halves the coarsest
//                      level's pixels once more, as Basalt's KITTI config does);
//   disparity_guesses_px  stereo starts for points without a predicted depth: EuRoC / TUM-VI
//                      0 12 30 55 85 120 (near points at 0.5 m: f b / z ≈ 100 px), KITTI
//                      0 10 25 45 70 (f b = 380 px·m: 70 px is a point 5.4 m away);
//   detect_margin_px   EuRoC / TUM-VI 0, KITTI 150: driving forward, points flow out of the sides
//                      of the wide image at 20–80 px per frame; of the keypoints detected in the
//                      outer 200 px of KITTI 06 only ~10 % were tracked into the next frame (a
//                      quarter predicted out of view, most of the rest failing the round trip),
//                      so new keypoints there cost a detection and a stereo match and mostly end
//                      after one frame. Tracks that reach the band go on until they leave.
// The resolved values are what a run records (the results file's config_toml).

#include <string>
#include <vector>

#include "core/common/enum_names.h"
#include "core/data/types.h"

namespace marglab {

// Where the front-end's motion prediction comes from (optical_flow.h, "Prediction"):
//   tracker   — the front-end's own frame-to-frame motion (its RANSAC, constant velocity) and its
//               stereo depths: the same tracks for every variant, so that variants differ only in
//               their numerics; track files and sweeps reproduce `run` bit for bit. The default:
//               on KITTI 06 the estimator's prediction made √VO-32 and √VO-64 differ by 7 % in
//               ATE through their tracks alone, this one by 0.0 % (README "Real images");
//   estimator — the estimator's predicted pose of the new frame (VO constant velocity, VIO IMU
//               propagation) and its landmark estimates, passed in by the run pipeline: the
//               front-end follows the variant's own estimate (a closed loop, as in a deployed
//               system);
//   none      — LK starts at the previous position (the front-end before prediction).
enum class MotionPredictionSource { kEstimator, kTracker, kNone };
inline constexpr EnumNames<MotionPredictionSource, 3> kMotionPredictionSourceNames{
    {{MotionPredictionSource::kEstimator, "estimator"},
     {MotionPredictionSource::kTracker, "tracker"},
     {MotionPredictionSource::kNone, "none"}}};
inline const char* toString(MotionPredictionSource value) {
  return nameOf(kMotionPredictionSourceNames, value);
}
inline bool parseMotionPredictionSource(const std::string& text, MotionPredictionSource* value) {
  return parseName(kMotionPredictionSourceNames, text, value);
}

struct FrontendOptions {
  int grid_cell_px = -1;        // −1: dataset default
  int pyramid_levels = -1;      // −1: dataset default; finest level included
  int max_iterations = 5;       // LK Gauss–Newton steps per pyramid level
  int window_px = 11;           // LK and NCC patch side (odd)
  double fb_max_px = 0.2;       // forward–backward check
  double epipolar_max = 0.005;  // |b0ᵀ E b1| of a stereo match (sine of the angle to the plane)
  double ncc_min = 0.7;         // zero-mean NCC of the tracked patch with its origin
  double ransac_px = 1.0;       // geometric check: reprojection error bound [pinhole px]
  double min_eigen = 3e-3;  // Shi–Tomasi λ_min at half resolution (OpenCV units: gradients / 255)
  int corner_block_px = 3;
  int border_px = 8;          // keypoints closer to the image edge are dropped
  int detect_margin_px = -1;  // −1: dataset default; no new keypoints this close to the left/right
                              // edges (tracks go on there)
  std::vector<double> disparity_guesses_px;  // empty: dataset default
  MotionPredictionSource prediction = MotionPredictionSource::kTracker;
};

// The options with every dataset-default sentinel replaced by the value for `kind`.
FrontendOptions resolveFrontendOptions(const FrontendOptions& options, DatasetKind kind);

}  // namespace marglab
