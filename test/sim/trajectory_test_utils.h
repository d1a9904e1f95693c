#pragma once
// Helpers of the trajectory-spline and IMU-synthesis tests: a smooth analytic trajectory sampled
// like a ground truth, and finite-difference tolerances.

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <limits>

#include "core/data/types.h"
#include "core/geometry/so3.h"

namespace marglab::test {

// A smooth hand-held-like motion: positions of ~1 m amplitude at 0.3–0.8 rad/s, attitude angles of
// ~0.5 rad, accelerations below 1 m/s².
inline Eigen::Vector3d analyticPosition(double t) {
  return {1.2 * std::sin(0.5 * t), 0.8 * std::cos(0.3 * t) + 0.2 * t,
          0.5 * std::sin(0.8 * t + 1.0)};
}

inline Eigen::Quaterniond analyticRotation(double t) {
  const Eigen::Vector3d phi(0.4 * std::sin(0.6 * t), 0.3 * std::cos(0.4 * t), 0.5 * t);
  return expSO3Quaternion<double>(phi);
}

// Samples of the analytic motion at t_start + k·period, k = 0 .. n−1, times in ns; samples in
// [gap_begin_s, gap_end_s) are dropped (to emulate a mocap gap).
inline Trajectory sampleAnalytic(int64_t t_start_ns, int64_t period_ns, int n,
                                 double gap_begin_s = 0, double gap_end_s = 0) {
  Trajectory gt;
  for (int k = 0; k < n; ++k) {
    const int64_t t_ns = t_start_ns + k * period_ns;
    const double t = static_cast<double>(t_ns - t_start_ns) * 1e-9;
    if (t >= gap_begin_s && t < gap_end_s) continue;
    gt.push_back(t_ns, analyticPosition(t), analyticRotation(t));
  }
  return gt;
}

inline double rotationAngle(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b) {
  return logSO3(Eigen::Quaterniond(R_a.transpose() * R_b)).norm();
}

constexpr double kEps = std::numeric_limits<double>::epsilon();

}  // namespace marglab::test
