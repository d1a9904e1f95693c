#pragma once
// C²-continuous trajectory through ground-truth poses, with analytic derivatives, for simulating
// IMU and camera measurements along a real trajectory (DESIGN §5).
//
// [The implementer states the maths here: spline type, how it interpolates the GT poses,
//  derivative formulas, frames.]

#include <Eigen/Core>
#include <cstdint>

#include "core/data/types.h"

namespace marglab {

// The state of the body at one instant, in double.
struct TrajectorySample {
  Eigen::Matrix3d R_w_b = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_w_b = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();      // velocity of the body origin, world frame
  Eigen::Vector3d a_w = Eigen::Vector3d::Zero();      // acceleration of the body origin, world
  Eigen::Vector3d omega_b = Eigen::Vector3d::Zero();  // angular velocity, body frame
};

// Anything that yields the body state at a time: the spline, or an analytic test trajectory.
class TrajectoryFunction {
 public:
  virtual ~TrajectoryFunction() = default;
  virtual int64_t startTimeNs() const = 0;
  virtual int64_t endTimeNs() const = 0;
  // Valid for startTimeNs() <= t_ns <= endTimeNs().
  virtual TrajectorySample evaluate(int64_t t_ns) const = 0;
};

}  // namespace marglab
