#pragma once
// When a run has lost the scene (failure_kind "tracking", results_file.h): the estimator keeps
// integrating — VO holds or extrapolates the last pose, VIO integrates the IMU alone — and a
// diverged or frozen trajectory would otherwise be reported "ok". The rule uses no ground truth,
// so a user's run without it fails the same way:
//   a frame is starved when fewer than min_tracked_observations of its observations continue
//   landmarks already in the window (FrameResult::n_connected: tracked, triangulated points the
//   estimator can use to constrain the new pose); max_tracking_loss_frames starved frames in a
//   row end the run. The first frame (which creates the window's landmarks) is never starved.
// It watches real measurements (frontend "images" and track files); simulated tracks are exempt:
// they thin out only where the simulated world ends past the trajectory's end (e.g. the last
// frames of a short clip), an edge of the simulation rather than a lost scene.
// Examples it catches: blank or black images (0 features), images too small for the grid (2
// features per frame), a front-end that continues almost none of its features after a jump.

#include <string>

#include "core/estimator/config.h"
#include "core/estimator/estimator.h"

namespace marglab {

class TrackingMonitor {
 public:
  explicit TrackingMonitor(const EstimatorConfig& config)
      : min_observations_(config.min_tracked_observations),
        max_frames_(config.max_tracking_loss_frames) {}

  // Called after each frame in order; the reason the run has lost the scene, or "".
  std::string update(int frame_index, const FrameResult& result);

 private:
  int min_observations_;
  int max_frames_;
  int starved_ = 0;  // starved frames in a row
};

}  // namespace marglab
