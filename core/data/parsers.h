#pragma once
// Parsers of the dataset file formats. Each reads one file (plain or .gz) and throws
// InputError(file, line, "expected …") on the first bad line. Common checks on every row:
// the column count, strictly numeric and finite fields, strictly increasing timestamps, and unit
// quaternions (|‖q‖ − 1| ≤ kQuaternionNormTolerance; the stored quaternion is then normalized).
//
// Formats (see datasets/README.md for the shipped files):
//   TUM trajectory      "t[s] x y z qx qy qz qw", space separated (quaternion x y z w).
//   ASL ground truth    "t[ns], p_x, p_y, p_z, q_w, q_x, q_y, q_z" (8 columns, TUM-VI mocap0) or
//   the
//                       same + v_xyz, b_w_xyz, b_a_xyz (17 columns, EuRoC
//                       state_groundtruth_estimate0).
//   ASL IMU             "t[ns], w_x, w_y, w_z, a_x, a_y, a_z".
//   Timestamp list      one int64 [ns] per line, or the ASL cam0/data.csv form "t[ns],filename".
//   EuRoC sensor.yaml   T_BS (4×4 data list, = T_b_c), intrinsics [fu fv cu cv], resolution,
//                       distortion_model, distortion_coefficients.
//   Kalibr camchain     camN: T_imu_cam or T_cam_imu (4×4 rows), intrinsics, resolution,
//                       distortion_model, distortion_coeffs.
//   Kalibr IMU yaml     [imu0:] gyroscope_noise_density, gyroscope_random_walk,
//                       accelerometer_noise_density, accelerometer_random_walk.
//   KITTI poses.txt     12 values per line: rows 0–2 of T_w_cam0, row-major; line i ↔ frame i.
//   KITTI times.txt     one time [s] per line, relative to the sequence start.
//   KITTI calib.txt     "P0: 12 values" … "P3: …": rectified 3×4 projections. cam0 = body;
//                       cam1 sits at +b along x with b = −P1[0,3]/P1[0,0].

#include <string>
#include <vector>

#include "core/data/plausibility.h"
#include "core/data/types.h"

namespace marglab {

// Loose on purpose: the VINS-Mono estimate of TUM-VI magistrale1 has norms up to 1.0024 (values
// written in float precision); a corrupted quaternion is far off.
inline constexpr double kQuaternionNormTolerance = 1e-2;
// Largest ‖RᵀR − I‖_max accepted for a rotation read from a file (KITTI stores 7 digits).
inline constexpr double kRotationTolerance = 1e-4;

// With `limits`, the trajectory and IMU readers also refuse implausible rows (core/data/
// plausibility.h: steps, speeds, IMU gaps and ranges) at their line.
Trajectory readTumTrajectory(const std::string& path, const PlausibilityLimits* limits = nullptr);

struct AslGroundTruth {
  Trajectory trajectory;
  std::optional<GtImuState> state;  // present for the 17-column EuRoC form
};
AslGroundTruth readAslGroundTruth(const std::string& path,
                                  const PlausibilityLimits* limits = nullptr);

ImuData readAslImu(const std::string& path, const PlausibilityLimits* limits = nullptr);

std::vector<int64_t> readTimestampList(const std::string& path);

// One camera of EuRoC (mav0/camN/sensor.yaml; T_BS = T_b_c, body = IMU).
CameraCalib readEurocSensorYaml(const std::string& path);
// Kalibr imu–camera chain with cam0 and cam1 (T_imu_cam or T_cam_imu; body = IMU).
StereoCalib readKalibrCamchain(const std::string& path);
ImuNoise readKalibrImuNoise(const std::string& path);

std::vector<int64_t> readKittiTimes(const std::string& path);
// `t_ns` are the frame times from times.txt; the file must have exactly one pose per time.
Trajectory readKittiPoses(const std::string& path, const std::vector<int64_t>& t_ns,
                          const PlausibilityLimits* limits = nullptr);
// Image size is not in calib.txt; KITTI odometry images are ≈1241×376 (the value ORB-SLAM3 and
// VINS-Fusion configure for every sequence).
StereoCalib readKittiCalib(const std::string& path, int width = 1241, int height = 376);

}  // namespace marglab
