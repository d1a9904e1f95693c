#pragma once
// Analytic test trajectories for the world / tracker tests (independent of the GT spline):
//   IndoorLoop  a drone in a room: p = (4 cos ωt, 3 sin ωt, 1.5 + 0.3 sin 2ωt), ω = 2π/40 s,
//               heading along the horizontal velocity plus a ±0.4 rad yaw wobble; body axes as
//               EuRoC's IMU (x up, z forward: the cam0 optical axis is ≈ body z).
//   StreetDrive a car on a gently curving road at 10 m/s: p = (8 sin(0.05 t), 0, 10 t) in a
//               y-down world; body = cam0 (x right, y down, z forward along the velocity).
// Only R_w_b and p_w_b (and v_w) are filled: the tracker reads nothing else.

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/sim/trajectory_spline.h"

namespace marglab::test {

class IndoorLoop : public TrajectoryFunction {
 public:
  explicit IndoorLoop(double duration_s = 60.0) : end_ns_(static_cast<int64_t>(duration_s * 1e9)) {}
  int64_t startTimeNs() const override { return 0; }
  int64_t endTimeNs() const override { return end_ns_; }
  TrajectorySample evaluate(int64_t t_ns) const override {
    const double t = static_cast<double>(t_ns) * 1e-9;
    const double w = 2 * M_PI / 40.0;
    TrajectorySample s;
    s.p_w_b =
        Eigen::Vector3d(4 * std::cos(w * t), 3 * std::sin(w * t), 1.5 + 0.3 * std::sin(2 * w * t));
    s.v_w = Eigen::Vector3d(-4 * w * std::sin(w * t), 3 * w * std::cos(w * t),
                            0.6 * w * std::cos(2 * w * t));
    const double yaw = std::atan2(s.v_w.y(), s.v_w.x()) + 0.4 * std::sin(0.7 * t);
    const Eigen::Vector3d up(0, 0, 1), h(std::cos(yaw), std::sin(yaw), 0);
    s.R_w_b.col(0) = up;
    s.R_w_b.col(1) = h.cross(up);
    s.R_w_b.col(2) = h;
    return s;
  }

 private:
  int64_t end_ns_;
};

class StreetDrive : public TrajectoryFunction {
 public:
  explicit StreetDrive(double duration_s = 30.0)
      : end_ns_(static_cast<int64_t>(duration_s * 1e9)) {}
  int64_t startTimeNs() const override { return 0; }
  int64_t endTimeNs() const override { return end_ns_; }
  TrajectorySample evaluate(int64_t t_ns) const override {
    const double t = static_cast<double>(t_ns) * 1e-9;
    TrajectorySample s;
    s.p_w_b = Eigen::Vector3d(8 * std::sin(0.05 * t), 0, 10 * t);
    s.v_w = Eigen::Vector3d(0.4 * std::cos(0.05 * t), 0, 10);
    const Eigen::Vector3d z = s.v_w.normalized(), y(0, 1, 0);
    s.R_w_b.col(0) = y.cross(z);
    s.R_w_b.col(1) = y;
    s.R_w_b.col(2) = z;
    return s;
  }

 private:
  int64_t end_ns_;
};

// Timestamps every period_ns from 0 up to end_ns.
inline std::vector<int64_t> uniformTimes(int64_t end_ns, int64_t period_ns) {
  std::vector<int64_t> t;
  for (int64_t x = 0; x <= end_ns; x += period_ns) t.push_back(x);
  return t;
}

}  // namespace marglab::test
