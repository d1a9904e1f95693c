#pragma once
// Plausibility limits of the real datasets, per dataset kind (docs/design.md §5, "Plausibility
// limits"): a value outside them is a corrupted or mistyped file, refused by the loaders and by
// `marglab datasets check` with a message naming the file, the line, the value and the limit.
//
// Why these numbers. EuRoC and TUM-VI are a MAV or a handheld rig: the shipped ground truth peaks
// at 28 m/s between two 5 ms samples (mocap glitches of EuRoC MH_04) and steps of 2.1 m across the
// 2.5 s gaps of TUM-VI room2; KITTI is a car at 10 Hz: 26 m/s and 2.7 m per step (sequence 01,
// highway). The limits leave a margin of ~2× over these and still refuse a pose moved by 1e5 m,
// which would otherwise make the simulated world around the path unboundedly large. The IMU limits
// are the sensors' ranges (EuRoC: ADIS16448, ±1000 °/s, ±18 g; TUM-VI: BMI160, ±2000 °/s, ±16 g)
// and at most 10 missing periods of the nominal 200 Hz (the shipped recordings have none).

#include <Eigen/Core>

#include <cstdint>
#include <string>

#include "core/data/types.h"

namespace marglab {

struct PlausibilityLimits {
  const char* platform;                   // what moves: "MAV / handheld rig", "car"
  double max_speed_mps;                   // |Δp| / Δt between consecutive poses
  double max_step_m;                      // |Δp| between consecutive poses, whatever Δt
  double note_path_length_m;              // below: a static or short recording (a note)
  double min_baseline_m, max_baseline_m;  // stereo baseline
  double imu_rate_hz;                     // nominal IMU rate (0: the dataset has no IMU)
  double max_imu_gap_s;                   // largest time between two IMU samples
  double max_gyro_radps;                  // per axis
  double max_accel_mps2;                  // per axis
};

const PlausibilityLimits& plausibilityLimits(DatasetKind kind);

// "" when the step from pose (t0, p0) to (t1, p1) is plausible, else what is wrong (value and
// limit). Times in ns, strictly increasing.
std::string poseStepProblem(const PlausibilityLimits& limits, int64_t t0_ns,
                            const Eigen::Vector3d& p0, int64_t t1_ns, const Eigen::Vector3d& p1);

// "" when an IMU sample is within the sensor's range and, unless it is the first, follows the
// previous one (t_prev_ns) within the gap limit, else what is wrong.
std::string imuSampleProblem(const PlausibilityLimits& limits, bool first, int64_t t_prev_ns,
                             int64_t t_ns, const Eigen::Vector3d& gyro,
                             const Eigen::Vector3d& accel);

// Throws InputError naming the sequence's files when the stereo baseline is outside its limits,
// cam1 is not to the right of cam0 (swapped cameras: a KITTI P1 of the wrong sign), or an
// intrinsic is beyond any real camera (fx, fy outside [20, 10000] px, the principal point outside
// the image, a distortion coefficient beyond ±5).
// Only the physically impossible is refused: a static or short recording (the MAV on the floor,
// a 5 s clip) is valid data, and gets a note (pathLengthNote).
void checkSequencePlausibility(const Sequence& sequence);

// "" when the trajectory moves at least note_path_length_m (or there is none), else a note for
// `datasets check` and `run`: "the trajectory moves 0.015 m over 5.0 s (a static or short
// recording: little motion to estimate)".
std::string pathLengthNote(const Sequence& sequence);

}  // namespace marglab
