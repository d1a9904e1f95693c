#pragma once
// The motion-consistency check of a run on real measurements (issue #38): frames out of order,
// or an estimate that jumps back and forth, end the run as a tracking failure. The tracking
// monitor (tracking_monitor.h) sees only the measurements; a KITTI copy with frames 25–30 shuffled
// keeps every track consistent with *some* pose, ran `ok`, and had five times the ATE.
//
// A car or a MAV moves smoothly at camera rate, so the estimated position p_k of frame k (time
// t_k) is close to the constant-velocity prediction from the two frames before it:
//
//   p̂_k = p_{k−1} + (p_{k−1} − p_{k−2}) (t_k − t_{k−1}) / (t_{k−1} − t_{k−2}),
//   jump_k = ‖p_k − p̂_k‖ / max(s_k, floor),
//
// where s_k is the median step ‖p_i − p_{i−1}‖ over the last kRecentSteps frames (the platform's
// own recent motion, so the rule holds for a car at 1.2 m per frame and a MAV at 2 cm alike) and
// floor (failure.motion_floor_m, 5 cm) keeps a standing platform's millimetre jitter from counting.
// jump_k > max_motion_jump (3) fails the run at frame k. It uses no ground truth.
//
// Measured (README "Failure said out loud"): on the ground truth of every shipped sequence at
// its camera times, the largest jump is 1.57 (TUM-VI room1; KITTI ≤ 1.02, EuRoC ≤ 1.21); real-image
// runs of KITTI 06 and EuRoC V1_01 stay below 0.07; the shuffled KITTI 06 copy reaches 8.0.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/pipeline/run_config.h"

namespace marglab {

class MotionCheck {
 public:
  explicit MotionCheck(const FailureSettings& failure)
      : max_jump_(failure.max_motion_jump), floor_m_(failure.motion_floor_m) {}

  // Called after each frame in order with its estimated position; the reason the run has failed,
  // or "".
  std::string update(int frame_index, std::int64_t t_ns, const Eigen::Vector3d& p_est);

 private:
  static constexpr int kRecentSteps = 10;

  double recentStep() const;

  double max_jump_;
  double floor_m_;
  std::vector<std::int64_t> t_ns_;  // the last two frames
  std::vector<Eigen::Vector3d> p_;
  std::vector<double> steps_;  // the last kRecentSteps steps
};

}  // namespace marglab
