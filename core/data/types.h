#pragma once
// Plain data types of the real datasets (EuRoC MAV, TUM-VI, KITTI odometry), in double precision
// and plain Eigen types, so that the loaders depend on nothing but Eigen.
//
// Frames and conventions:
//   w  world (EuRoC/TUM-VI: the mocap/Leica frame "R"; KITTI: cam0 at frame 0),
//   b  body  (EuRoC/TUM-VI: the IMU frame "S"; KITTI: the left grey camera cam0),
//   c  camera (optical frame: z forward, x right, y down).
//   T_w_b maps body coordinates to world coordinates: p_w = R_w_b p_b + p_w_b, with R_w_b = q_w_b.
//   T_b_c maps camera coordinates to body coordinates: p_b = R_b_c p_c + t_b_c.
// Times are int64 nanoseconds. EuRoC/TUM-VI times are the sensors' epoch timestamps; KITTI times
// are the seconds of times.txt (relative to the sequence start) converted to ns.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace marglab {

// A stamped pose sequence, structure of arrays (all three vectors have the same size).
struct Trajectory {
  std::vector<int64_t> t_ns;
  std::vector<Eigen::Vector3d> p_w_b;
  std::vector<Eigen::Quaterniond> q_w_b;  // unit quaternions (normalized by the loaders)

  std::size_t size() const { return t_ns.size(); }
  bool empty() const { return t_ns.empty(); }
  void push_back(int64_t t, const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
    t_ns.push_back(t);
    p_w_b.push_back(p);
    q_w_b.push_back(q);
  }
};

// Raw IMU samples in the body (IMU) frame: gyro ω [rad/s], specific force a [m/s²].
struct ImuData {
  std::vector<int64_t> t_ns;
  std::vector<Eigen::Vector3d> gyro;
  std::vector<Eigen::Vector3d> accel;

  std::size_t size() const { return t_ns.size(); }
  bool empty() const { return t_ns.empty(); }
};

// Velocity and IMU biases of the EuRoC ground-truth csv (17 columns), one row per GT pose.
struct GtImuState {
  std::vector<Eigen::Vector3d> v_w_b;       // [m/s], world frame
  std::vector<Eigen::Vector3d> bias_gyro;   // [rad/s]
  std::vector<Eigen::Vector3d> bias_accel;  // [m/s²]
};

// Continuous-time IMU noise (Kalibr convention). The discrete noise of a sample spaced Δt is
// σ/√Δt; the bias random walk over Δt has std σ_rw √Δt.
struct ImuNoise {
  double gyro_noise_density = 1.6968e-4;  // [rad/s/√Hz]
  double gyro_random_walk = 1.9393e-5;    // [rad/s²/√Hz]
  double accel_noise_density = 2.0e-3;    // [m/s²/√Hz]
  double accel_random_walk = 3.0e-3;      // [m/s³/√Hz]
};

// One camera. The simulator projects with the pinhole part (fx, fy, cx, cy) only: measurements are
// synthesized in an undistorted image. The original distortion model and coefficients are kept for
// reference and for external front-ends; nothing in marglab applies them.
struct CameraCalib {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;
  std::string distortion_model;  // "radtan", "equidistant", or "none" (KITTI, rectified)
  std::vector<double> distortion;
  Eigen::Matrix3d R_b_c = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t_b_c = Eigen::Vector3d::Zero();
};

struct StereoCalib {
  CameraCalib cam0;
  CameraCalib cam1;
  // Distance between the two optical centres [m].
  double baseline() const { return (cam1.t_b_c - cam0.t_b_c).norm(); }
};

enum class DatasetKind { kEuroc, kTumvi, kKitti };
const char* datasetKindName(DatasetKind kind);  // "euroc", "tumvi", "kitti"

// Estimator defaults that depend on the dataset (docs/design.md §3–5).
struct DatasetDefaults {
  double grid_cell_px;          // feature detection grid: 50 px EuRoC/TUM-VI, 30 px KITTI
  double max_position_error_m;  // failure bound on position error: 5 m indoor, 100 m KITTI
  int min_frames_after_kf;      // keyframe spacing: 5 EuRoC/TUM-VI, 1 KITTI
};
DatasetDefaults datasetDefaults(DatasetKind kind);

// Everything the simulator and estimator need from one real sequence.
//
// A sequence may have no trajectory at all (TUM-VI corridor2, magistrale2, slides1, slides2: only
// camera timestamps could be shipped). It loads, `hasTrajectory()` is false, and consumers that
// need poses must refuse it with a clear message. When `gt_is_estimate` is true the trajectory is a
// smooth VIO output (OKVIS / VINS-Mono), usable to simulate from but not ground truth.
struct Sequence {
  DatasetKind kind = DatasetKind::kEuroc;
  std::string name;       // "euroc/MH_01_easy", "tumvi/room1", "kitti/00", or the folder name
  std::string directory;  // where it was loaded from
  Trajectory gt;          // T_w_b (KITTI: T_w_cam0)
  bool gt_is_estimate = false;
  std::string gt_source;          // e.g. "ASL csv", "TUM txt", "OKVIS estimate", "KITTI poses"
  std::string gt_file;            // path of the trajectory file ("" when there is none)
  std::vector<int64_t> cam_t_ns;  // cam0 frame timestamps
  std::string cam_file;
  std::optional<ImuData> imu;  // real IMU recording, when available
  std::string imu_file;
  std::optional<GtImuState> gt_imu_state;  // GT velocity + biases (EuRoC ASL csv only)
  StereoCalib calib;
  std::string calib_source;  // file(s) the camera calibration was read from
  ImuNoise imu_noise;
  DatasetDefaults defaults{50.0, 5.0, 5};

  bool hasTrajectory() const { return !gt.empty(); }
};

}  // namespace marglab
