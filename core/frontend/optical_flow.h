#pragma once
// A stereo optical-flow front-end in the spirit of Basalt's (Usenko et al., "Visual-Inertial
// Mapping with Non-Linear Factor Recovery", RA-L 2020), on OpenCV's pyramidal Lucas–Kanade
// (Bouguet's implementation). Settings: frontend_options.h (config section [frontend]).
//
// Per stereo frame k (raw, distorted images I0_k, I1_k; keypoints live in raw pixels). Each image
// gets one pyramid, built once and shared by the temporal tracking, the backward checks and the
// stereo match (the previous left pyramid is kept for the next frame).
//   1. Prediction. LK converges only within a few pixels of its start at the coarsest level, and
//      on 10 Hz driving data features move tens of pixels per frame, so each keypoint's LK starts
//      where the motion estimate puts it: with T_new_prev (motion_prediction.h) and the point's
//      position p_prev in the previous cam0 (the estimator's landmark, else the front-end's own
//      stereo triangulation of the previous frame, else its ray at the depth of the nearest
//      keypoint with a stereo point within two grid cells), x_start = d(π(T_new_prev p_prev)), and
//      its patch's predicted zoom is z_prev / z_new; a point with no depth at all is predicted at
//      infinity (rotation only, R_new_prev b_prev). On KITTI 06, 40 % of the fresh keypoints have
//      no stereo match yet, and at infinity their start was ~20 px off. A point predicted
//      outside the image has left the view: its track ends. Without an estimate (first frames,
//      prediction "none") LK starts at the previous position. With prediction "tracker" the motion
//      is the front-end's own: the previous frame's RANSAC motion (step 3), constant velocity.
//   2. Temporal tracking: LK on `pyramid_levels` levels, ≤ max_iterations steps per level, then
//      the forward–backward check: x' is tracked back into I0_{k−1} from x' − (x_start − x); the
//      track continues only if it returns within fb_max_px of x (a point LK cannot map
//      consistently both ways sits on an occlusion boundary or a repetitive texture), and the
//      patch check: the zero-mean normalized cross-correlation of the window_px patches around x
//      in I0_{k−1} and x' in I0_k is ≥ ncc_min (a consistent alignment onto a different texture —
//      an occluder that moved in — passes the round trip but not this).
//   2b. A track predicted in view that failed step 2 gets a second chance (with a prediction): the
//      patch tracker of affine_patch_tracker.h with the patch zoomed by its predicted scale, the
//      same round-trip (fb_max_px) and patch (ncc_min) checks after the zoom. Translation-only LK
//      fails more the farther a point moves (KITTI 06 fresh keypoints: 6 % at < 5 px, 41 % at
//      40–80 px), where driving forward also zooms the patch.
//   3. Geometric check (per frame): the tracks with a stereo depth in the previous frame give 3-D
//      points p_prev and their new undistorted pixels; P3P in RANSAC (cv::solvePnPRansac, fixed
//      seed: deterministic) finds the motion T_new_prev that most of them agree with to ransac_px
//      pinhole pixels. Tracks it calls outliers end; tracks without depth must satisfy the
//      epipolar constraint of that motion, |b_newᵀ [t̂]× R b_prev| ≤ epipolar_max, when the motion
//      has a baseline (‖t‖ ≥ 0.02 m). The motion is the frame's `motion` statistic and the
//      tracker's prediction for the next frame.
//   4. Detection: the image is divided into grid_cell_px cells; in a cell that holds no tracked
//      point, the pixel with the largest Shi–Tomasi response λ_min(M) (M = 2×2 structure tensor
//      over a block) starts a new track if λ_min ≥ min_eigen (a flat cell gets nothing). No new
//      keypoint within detect_margin_px of the left and right edges (KITTI: points there leave
//      the view within a frame or two; frontend_options.h).
//   5. Stereo: every keypoint of I0_k is tracked into I1_k with the same forward–backward and
//      patch checks, LK starting from its predicted 3-D point projected into cam1 (when it has
//      one), else its track's disparity of the previous frame, else the pixels of the disparity
//      guesses along the epipolar line until one passes; then the epipolar check with unit
//      bearings b0, b1 of the undistorted keypoints and E = [t̂]× R (R, t = T_c0_c1):
//      |b0ᵀ E b1| ≤ epipolar_max. A match gives the point's depth by triangulation (the
//      least-squares depths along both rays), kept for the next frame's prediction.
//   6. Undistortion: keypoints are mapped into the estimator's pinhole image (camera_model.h); a
//      left keypoint that cannot be undistorted ends its track, a right one loses its match.
// The output is a TrackFrame (tracks.h) like the simulator's: track ids count from 0 in order of
// detection; landmark_id = −1, is_outlier = false (unknown for real images).
//
// Determinism: OpenCV runs single-threaded (cv::setNumThreads(1) in the constructor), RANSAC has a
// fixed seed, and every step is a pure function of the images and the prediction, so the same
// images and predictions give the same tracks bit for bit.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/data/tracks.h"
#include "core/data/types.h"
#include "core/frontend/camera_model.h"
#include "core/frontend/frontend_options.h"
#include "core/frontend/motion_prediction.h"
#include "core/io/results_records.h"

namespace marglab {

// The options of a sequence: `configured` with its dataset-default sentinels resolved.
FrontendOptions defaultFrontendOptions(const Sequence& sequence,
                                       const FrontendOptions& configured = FrontendOptions{});

// Per frame statistics: the frame's /frontend row (n_features: the observations handed to the
// estimator; t_frontend_s: wall time of tracking + detection + stereo + undistortion) and what
// the file does not store.
struct FrontendFrameStats : FrontendRecord {
  int n_continued_depth = 0;  // continued tracks that had a stereo depth in the previous frame
  int n_motion_inliers = -1;  // the geometric check's inliers (−1: no motion this frame)
  int n_motion_points = 0;    // tracks with depth it was run on
  bool has_motion = false;    // T_new_prev below is the geometric check's motion
  SE3<double> T_new_prev;     // cam0 motion from the previous frame (step 3)
  double cpu_frontend_s = 0;  // t_frontend_s in CPU time of the process (one thread: the speed)
};

// Forward-tracked candidates of one frame, before the forward–backward check (for tests that
// know the true pixel positions): raw pixels in I0_{k−1} and I0_k, and whether the track went on.
struct FlowCandidate {
  int64_t track_id = -1;
  double u_prev = 0, v_prev = 0, u = 0, v = 0;
  bool lk_ok = false;  // LK converged and stayed in the image
  bool kept = false;   // also passed the forward–backward, patch and geometric checks
};

class StereoFrontend {
 public:
  StereoFrontend(const StereoCalib& calib, const FrontendOptions& options,
                 const std::string& calib_source);
  ~StereoFrontend();
  StereoFrontend(StereoFrontend&&) noexcept;
  StereoFrontend& operator=(StereoFrontend&&) noexcept;

  // One stereo frame of 8-bit grey images of the calibration's size. `prediction` (prediction
  // "estimator") overrides the tracker's own; with options.prediction "none" it is ignored.
  TrackFrame process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                     FrontendFrameStats* stats = nullptr,
                     std::vector<FlowCandidate>* candidates = nullptr,
                     const FramePrediction* prediction = nullptr);

  // Raw (distorted) left keypoints of the last frame, in the order of its observations.
  const std::vector<Eigen::Vector2d>& lastRawLeft() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Reads an 8-bit grey image and checks its size; InputError naming the file when it is missing,
// cannot be decoded or has another size (width, height ≤ 0: no size check).
cv::Mat readGreyImage(const std::string& path, int width, int height);

}  // namespace marglab
