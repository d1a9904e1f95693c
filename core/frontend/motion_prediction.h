#pragma once
// What the front-end is told about the motion before it tracks a new frame (optical_flow.h,
// "Prediction"). The run pipeline fills it from the estimator (its predicted pose of the new frame
// and its landmark estimates); the front-end never includes the estimator, so the dependency is
// one-directional: estimator → pipeline → FramePrediction → front-end.
//
// Frames: c = the left camera cam0, "prev" the previous image's, "new" the image about to be
// tracked. A point seen at p_prev is expected at p_new = T_new_prev p_prev, i.e. at the raw pixel
// d(π(p_new)) (π the pinhole projection, d the camera's distortion, camera_model.h).

#include <Eigen/Core>

#include <cstdint>
#include <unordered_map>

#include "core/geometry/se3.h"

namespace marglab {

struct FramePrediction {
  SE3<double> T_new_prev;  // predicted motion of cam0 from the previous image to the new one
  // Landmark estimates in the previous image's cam0, by track id. Tracks without one use the
  // front-end's stereo triangulation of the previous image, else infinite depth (rotation only).
  std::unordered_map<int64_t, Eigen::Vector3d> p_prev;
};

}  // namespace marglab
