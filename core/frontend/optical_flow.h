#pragma once
// A stereo optical-flow front-end in the spirit of Basalt's (Usenko et al., "Visual-Inertial
// Mapping with Non-Linear Factor Recovery", RA-L 2020, its EuRoC settings), on OpenCV's pyramidal
// Lucas–Kanade (Bouguet's implementation).
//
// Per stereo frame k (raw, distorted images I0_k, I1_k; keypoints live in raw pixels):
//   1. Temporal tracking: every keypoint x of I0_{k−1} is tracked to I0_k by LK on a
//      `pyramid_levels`-level pyramid, ≤ max_iterations Gauss–Newton steps per level, giving x'.
//      Forward–backward check: x' is tracked back to I0_{k−1}, giving x''; the track continues
//      only if ‖x'' − x‖ ≤ fb_max_px (0.2 px: a point that LK cannot map consistently both ways
//      sits on an occlusion boundary, on a repetitive texture or has moved out of view).
//   2. Detection: the image is divided into grid_cell_px cells; in a cell that holds no tracked
//      point, the pixel with the largest Shi–Tomasi response λ_min(M) (M = 2×2 structure tensor
//      over a block) starts a new track if λ_min ≥ min_eigen (a flat cell gets nothing).
//   3. Stereo: every keypoint of I0_k is tracked into I1_k with the same forward–backward check,
//      LK starting from its track's disparity of the previous frame, else (or if that fails) from
//      the pixels of a few disparity hypotheses along the epipolar line (0, 12, 30, 55 px: LK
//      only converges from a few pixels away at the coarsest level, and near points have large
//      disparities) until one passes; then the epipolar check: with unit bearings b0, b1 of the
//      undistorted keypoints and E = [t̂]× R (R, t = T_c0_c1, t̂ = t/‖t‖),  |b0ᵀ E b1| ≤
//      epipolar_max (the sine of the angle between b0 and the epipolar plane of b1; Basalt 0.005).
//   4. Undistortion: keypoints are mapped into the estimator's pinhole image (camera_model.h); a
//      left keypoint that cannot be undistorted ends its track, a right one loses its match.
// The output is a TrackFrame (tracks.h) like the simulator's: track ids count from 0 in order of
// detection; landmark_id = −1, is_outlier = false (unknown for real images).
//
// Determinism: OpenCV runs single-threaded (cv::setNumThreads(1) in the constructor), and every
// step is a pure function of the images, so the same images give the same tracks bit for bit.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/data/types.h"
#include "core/frontend/camera_model.h"
#include "core/sim/tracks.h"

namespace marglab {

struct FrontendOptions {
  int grid_cell_px = 50;
  int pyramid_levels = 3;  // finest level included (OpenCV maxLevel = levels − 1)
  int max_iterations = 5;  // per pyramid level
  int window_px = 21;      // LK patch side
  double fb_max_px = 0.2;  // forward–backward check
  double epipolar_max = 0.005;
  double min_eigen = 1e-3;  // Shi–Tomasi λ_min (OpenCV units: gradients / 255, block-averaged)
  int corner_block_px = 3;
  int border_px = 8;  // keypoints closer to the image edge are dropped
  // Stereo: starts of the left→right LK after the previous frame's disparity (see matchStereo).
  std::vector<double> stereo_disparity_guesses_px = {0, 12, 30, 55, 85, 120};
};
// The EuRoC / TUM-VI defaults above; KITTI: the dataset's 30 px grid (DatasetDefaults).
FrontendOptions defaultFrontendOptions(const Sequence& sequence);

// Per frame statistics (the results file's /frontend group).
struct FrontendFrameStats {
  int64_t t_ns = 0;
  int n_features = 0;         // observations handed to the estimator
  int n_tracked = 0;          // of those, continued from the previous frame
  int n_new = 0;              // detected in this frame
  int n_stereo = 0;           // with a right match
  double t_frontend_s = 0;    // wall time of tracking + detection + stereo + undistortion
  double cpu_frontend_s = 0;  // the same in CPU time of the process (one thread: the speed)
};

// Forward-tracked candidates of one frame, before the forward–backward check (for tests that
// know the true pixel positions): raw pixels in I0_{k−1} and I0_k, and whether the track went on.
struct FlowCandidate {
  int64_t track_id = -1;
  double u_prev = 0, v_prev = 0, u = 0, v = 0;
  bool lk_ok = false;  // LK converged and stayed in the image
  bool kept = false;   // also passed the forward–backward check and the undistortion
};

class StereoFrontend {
 public:
  StereoFrontend(const StereoCalib& calib, const FrontendOptions& options,
                 const std::string& calib_source);
  ~StereoFrontend();
  StereoFrontend(StereoFrontend&&) noexcept;
  StereoFrontend& operator=(StereoFrontend&&) noexcept;

  // One stereo frame of 8-bit grey images of the calibration's size.
  TrackFrame process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                     FrontendFrameStats* stats = nullptr,
                     std::vector<FlowCandidate>* candidates = nullptr);

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
