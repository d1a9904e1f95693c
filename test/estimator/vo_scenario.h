#pragma once
// The VO estimator tests' street-like scenario: an analytic trajectory and a KITTI-like rectified
// stereo rig, as calibration and as the estimator's camera model (test_vo.cpp,
// test_stereo_offset.cpp, test_window_consistency.cpp).

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>

#include "core/data/types.h"
#include "core/geometry/camera.h"
#include "core/sim/trajectory_spline.h"

namespace marglab::test {

// A camera (body = cam0, z forward, y down) driving on a circle of radius r in the x-z plane at
// angular rate w, with a small vertical oscillation.
class CircleTrajectory : public TrajectoryFunction {
 public:
  static constexpr double kRadius = 100.0, kRate = 0.08, kBob = 0.2;
  int64_t startTimeNs() const override { return 0; }
  int64_t endTimeNs() const override { return 60'000'000'000; }
  TrajectorySample evaluate(int64_t t_ns) const override {
    const double t = 1e-9 * static_cast<double>(t_ns);
    const double th = kRate * t;
    TrajectorySample s;
    s.R_w_b = Eigen::AngleAxisd(th, Eigen::Vector3d::UnitY()).toRotationMatrix();
    s.p_w_b = Eigen::Vector3d(kRadius * (1 - std::cos(th)), kBob * std::sin(2 * t),
                              kRadius * std::sin(th));
    s.v_w = Eigen::Vector3d(kRadius * kRate * std::sin(th), 2 * kBob * std::cos(2 * t),
                            kRadius * kRate * std::cos(th));
    s.a_w = Eigen::Vector3d(kRadius * kRate * kRate * std::cos(th), -4 * kBob * std::sin(2 * t),
                            -kRadius * kRate * kRate * std::sin(th));
    s.omega_b = Eigen::Vector3d(0, kRate, 0);
    return s;
  }
};

inline StereoCalib kittiLikeCalib() {
  StereoCalib calib;
  for (CameraCalib* cam : {&calib.cam0, &calib.cam1}) {
    cam->fx = cam->fy = 718.856;
    cam->cx = 607.1928;
    cam->cy = 185.2157;
    cam->width = 1241;
    cam->height = 376;
    cam->distortion_model = "none";
  }
  calib.cam1.t_b_c = Eigen::Vector3d(0.537, 0, 0);
  return calib;
}

// The same rig as the estimator's camera model (the window tests).
inline StereoRig<double> kittiLikeRig() {
  StereoRig<double> rig;
  rig.cam0 = PinholeCamera<double>{718.856, 718.856, 607.193, 185.216, 1241, 376};
  rig.cam1 = rig.cam0;
  rig.T_i_c1 = SE3<double>(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.537, 0, 0));
  return rig;
}

}  // namespace marglab::test
