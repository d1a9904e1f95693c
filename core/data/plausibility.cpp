#include "core/data/plausibility.h"

#include <fmt/core.h>

#include <cmath>
#include <utility>

#include "core/common/error.h"

namespace marglab {

namespace {

// The one table of limits (docs/design.md §5 lists the same numbers).
constexpr PlausibilityLimits kMavLimits{
    "MAV / handheld rig", 50.0, 10.0, 1.0, 0.02, 1.0, 200.0, 0.05, 17.5, 176.5};
constexpr PlausibilityLimits kTumviLimits{
    "MAV / handheld rig", 50.0, 10.0, 1.0, 0.02, 1.0, 200.0, 0.05, 34.9, 156.9};
constexpr PlausibilityLimits kCarLimits{"car", 70.0, 10.0, 1.0, 0.1, 3.0, 0.0, 0.0, 0.0, 0.0};

}  // namespace

const PlausibilityLimits& plausibilityLimits(DatasetKind kind) {
  switch (kind) {
    case DatasetKind::kEuroc:
      return kMavLimits;
    case DatasetKind::kTumvi:
      return kTumviLimits;
    case DatasetKind::kKitti:
      return kCarLimits;
  }
  return kMavLimits;
}

std::string poseStepProblem(const PlausibilityLimits& limits, int64_t t0_ns,
                            const Eigen::Vector3d& p0, int64_t t1_ns, const Eigen::Vector3d& p1) {
  const double step = (p1 - p0).norm();
  const double dt_s = 1e-9 * static_cast<double>(t1_ns - t0_ns);
  if (!(step <= limits.max_step_m)) {
    return fmt::format(
        "expected a step of at most {:g} m from the previous pose ({}), found {:.6g} m",
        limits.max_step_m, limits.platform, step);
  }
  if (!(step <= limits.max_speed_mps * dt_s)) {
    return fmt::format(
        "expected a speed of at most {:g} m/s from the previous pose ({}), found {:.6g} m in "
        "{:.6g} s = {:.6g} m/s",
        limits.max_speed_mps, limits.platform, step, dt_s, step / dt_s);
  }
  return {};
}

std::string imuSampleProblem(const PlausibilityLimits& limits, bool first, int64_t t_prev_ns,
                             int64_t t_ns, const Eigen::Vector3d& gyro,
                             const Eigen::Vector3d& accel) {
  const double gap_s = 1e-9 * static_cast<double>(t_ns - t_prev_ns);
  if (!first && gap_s > limits.max_imu_gap_s) {
    return fmt::format(
        "expected IMU samples at most {:g} s apart (nominal {:g} Hz), found a gap of {:.6g} s "
        "after t = {} ns",
        limits.max_imu_gap_s, limits.imu_rate_hz, gap_s, t_prev_ns);
  }
  if (gyro.cwiseAbs().maxCoeff() > limits.max_gyro_radps) {
    return fmt::format(
        "expected angular rates within ±{:g} rad/s (the gyroscope's range), found {:.6g}",
        limits.max_gyro_radps, gyro.cwiseAbs().maxCoeff());
  }
  if (accel.cwiseAbs().maxCoeff() > limits.max_accel_mps2) {
    return fmt::format(
        "expected accelerations within ±{:g} m/s² (the accelerometer's range), found {:.6g}",
        limits.max_accel_mps2, accel.cwiseAbs().maxCoeff());
  }
  return {};
}

std::string pathLengthNote(const Sequence& seq) {
  if (!seq.hasTrajectory()) return {};
  double length = 0;
  for (std::size_t i = 1; i < seq.gt.size(); ++i) {
    length += (seq.gt.p_w_b[i] - seq.gt.p_w_b[i - 1]).norm();
  }
  if (length >= plausibilityLimits(seq.kind).note_path_length_m) return {};
  return fmt::format(
      "the trajectory moves {:.3g} m over {:.1f} s ({} poses): a static or short recording, "
      "little motion to estimate",
      length, 1e-9 * static_cast<double>(seq.gt.t_ns.back() - seq.gt.t_ns.front()), seq.gt.size());
}

namespace {

// Intrinsics no real camera of these datasets comes near (EuRoC fx 458 px, TUM-VI 190 px, KITTI
// 718 px; |k| ≤ 0.3): a mistyped or corrupted calibration, refused like an impossible pose.
constexpr double kMinFocalPx = 20, kMaxFocalPx = 10000, kMaxDistortion = 5;

void checkIntrinsics(const CameraCalib& cam, const char* which, const std::string& source) {
  const auto refuse = [&](const std::string& what) {
    throw InputError(source, 0, fmt::format("{}: expected {}", which, what));
  };
  for (const auto& [name, f] : {std::pair<const char*, double>{"fx", cam.fx}, {"fy", cam.fy}}) {
    if (!(f >= kMinFocalPx && f <= kMaxFocalPx)) {
      refuse(fmt::format("{} in [{:g}, {:g}] px (any real camera), found {:.6g}", name, kMinFocalPx,
                         kMaxFocalPx, f));
    }
  }
  const double w = cam.width > 0 ? cam.width : kMaxFocalPx;  // KITTI: no size in calib.txt
  const double h = cam.height > 0 ? cam.height : kMaxFocalPx;
  if (!(cam.cx >= 0 && cam.cx <= w && cam.cy >= 0 && cam.cy <= h)) {
    refuse(
        fmt::format("the principal point inside the image [0, {:g}] x [0, {:g}] px, found "
                    "({:.6g}, {:.6g})",
                    w, h, cam.cx, cam.cy));
  }
  for (const double k : cam.distortion) {
    if (!(std::abs(k) <= kMaxDistortion)) {
      refuse(fmt::format("distortion coefficients within ±{:g}, found {:.6g}", kMaxDistortion, k));
    }
  }
}

}  // namespace

void checkSequencePlausibility(const Sequence& seq) {
  const PlausibilityLimits& limits = plausibilityLimits(seq.kind);
  checkIntrinsics(seq.calib.cam0, "cam0", seq.calib_source);
  checkIntrinsics(seq.calib.cam1, "cam1", seq.calib_source);
  const double baseline = seq.calib.baseline();
  if (!(baseline >= limits.min_baseline_m && baseline <= limits.max_baseline_m)) {
    throw InputError(
        seq.calib_source, 0,
        fmt::format("expected a stereo baseline in [{:g}, {:g}] m ({}), found {:.6g} m",
                    limits.min_baseline_m, limits.max_baseline_m, limits.platform, baseline));
  }
  // cam1 is the right camera: its centre lies on cam0's +x side (a P1 with the wrong sign swaps
  // the cameras, and the stereo matching then finds next to nothing).
  const Eigen::Vector3d c1_in_c0 =
      seq.calib.cam0.R_b_c.transpose() * (seq.calib.cam1.t_b_c - seq.calib.cam0.t_b_c);
  if (!(c1_in_c0.x() > 0)) {
    throw InputError(seq.calib_source, 0,
                     fmt::format("expected cam1 to the right of cam0 (+x of cam0), found it at "
                                 "x = {:.6g} m: are the cameras swapped (the sign of P1's "
                                 "translation)?",
                                 c1_in_c0.x()));
  }
}

}  // namespace marglab
