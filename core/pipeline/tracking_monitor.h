#pragma once
// When a run has lost the scene (failure_kind "tracking", results_file.h): the estimator keeps
// integrating — VO holds or extrapolates the last pose, VIO integrates the IMU alone — and a
// diverged or frozen trajectory would otherwise be reported "ok". The rule uses no ground truth,
// so a user's run without it fails the same way. A frame (the first, which creates the window's
// landmarks, aside) is lost when it is
//   starved       fewer than min_tracked_observations of its observations continue landmarks
//                 already in the window (FrameResult::n_connected: tracked, triangulated points
//                 the estimator can use to constrain the new pose), or
//   inconsistent  after the optimization, more than max_inconsistent_share of the observations it
//                 shares with the window (FrameResult::n_checked, at least min_tracked_observations
//                 of them) lie farther than inconsistent_px from their landmark's projection
//                 (n_inconsistent): the tracks continue but no pose explains them — wrong
//                 associations, a scene that moves, an estimate that has left the scene. On real
//                 frames such observations are a fraction of a percent (KITTI 06 ≤ 0.7 % beyond
//                 5 px, EuRoC V1_01 none; README "Failure said out loud").
// max_tracking_loss_frames lost frames in a row end the run.
// It watches real measurements (frontend "images" and track files); simulated tracks are exempt:
// they thin out only where the simulated world ends past the trajectory's end (e.g. the last
// frames of a short clip), an edge of the simulation rather than a lost scene.
// Examples it catches: blank or black images (0 features), images too small for the grid (2
// features per frame), a front-end that continues almost none of its features after a jump, half
// of a frame's tracks associated with the wrong landmarks.

#include <string>

#include "core/estimator/estimator.h"
#include "core/pipeline/run_config.h"

namespace marglab {

class TrackingMonitor {
 public:
  explicit TrackingMonitor(const FailureSettings& failure)
      : min_observations_(failure.min_tracked_observations),
        max_frames_(failure.max_tracking_loss_frames),
        inconsistent_px_(failure.inconsistent_px),
        max_inconsistent_share_(failure.max_inconsistent_share) {}

  // Called after each frame in order; the reason the run has lost the scene, or "".
  std::string update(int frame_index, const FrameResult& result);

 private:
  bool inconsistent(const FrameResult& result) const;

  int min_observations_;
  int max_frames_;
  double inconsistent_px_;
  double max_inconsistent_share_;
  int lost_ = 0;  // lost frames in a row
};

}  // namespace marglab
