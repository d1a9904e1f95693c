#pragma once
// The feature-track stream: what a stereo front-end (simulated, or KLT on real images) hands to
// the estimator. One TrackFrame per cam0 timestamp.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace marglab {

struct StereoObservation {
  int64_t track_id = -1;   // unique per track; a re-detected point gets a new id
  Eigen::Vector2d uv0;     // pixel in cam0 (undistorted pinhole image)
  bool has_right = false;  // stereo match found in cam1
  Eigen::Vector2d uv1 = Eigen::Vector2d::Zero();
  // Simulation ground truth (−1 / false for external front-ends): which world point, and whether
  // this measurement was replaced by an outlier. Only statistics and tests read these.
  int64_t landmark_id = -1;
  bool is_outlier = false;
};

struct TrackFrame {
  int64_t t_ns = 0;
  std::vector<StereoObservation> observations;
};

struct TrackStream {
  std::string sequence;  // e.g. "euroc/MH_01_easy"
  uint64_t seed = 0;
  std::vector<TrackFrame> frames;
  std::vector<Eigen::Vector3d> landmarks_w;  // simulation ground truth, indexed by landmark_id
};

}  // namespace marglab
