#pragma once
// Synthetic IMU measurements along a trajectory (docs/design.md §5), and the real IMU of a sequence
// clipped to the trajectory span.
//
// Model (body frame b = IMU frame; world w with gravity g_w), at t_k = t_start + k Δt:
//   ω_k = ω_b(t_k) + b_g,k + n_g,k
//   a_k = R_w_b(t_k)ᵀ (a_w(t_k) − g_w) + b_a,k + n_a,k        (specific force)
//   n_·,k ~ N(0, σ_·² / Δt)  per axis            (white noise density σ [unit/√Hz] sampled at Δt)
//   b_·,k+1 = b_·,k + N(0, σ_rw,·² Δt)  per axis  (bias random walk density σ_rw [unit·√Hz])
// with the Kalibr densities of ImuNoise (EuRoC: σ_g = 1.6968e-4, σ_rw,g = 1.9393e-5,
// σ_a = 2.0e-3, σ_rw,a = 3.0e-3) and b_·,0 from the options (default 0).
// The biases are returned per sample, the true values for evaluating bias estimates.
//
// Random numbers: std::mt19937_64 (its output sequence is fixed by the C++ standard) turned into
// N(0, 1) by the Box–Muller transform implemented here, so that a seed gives the same
// measurements with every standard library (std::normal_distribution is not specified exactly).
// Per sample the draws are, in order: n_g (3), n_a (3), walk of b_g (3), walk of b_a (3), each
// group only when enabled.
//
// Gravity: the simulator and the estimator must agree on g_w. EuRoC and TUM-VI worlds are
// gravity-aligned with z up: g_w = (0, 0, −9.81). KITTI's world is cam0 at the first frame
// (x right, y down, z forward), so gravity is ≈ (0, +9.81, 0) there, up to the camera's small
// pitch/roll at frame 0, which the poses do not record; gravityWorld() returns these.

#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <vector>

#include "core/common/enum_names.h"
#include "core/data/types.h"
#include "core/sim/trajectory_spline.h"

namespace marglab {

constexpr double kGravityMagnitude = 9.81;

// g_w of a dataset's world frame (see the header comment).
Eigen::Vector3d gravityWorld(DatasetKind kind);

// N(0, 1) samples from mt19937_64 by Box–Muller; reproducible across standard libraries.
class StandardNormal {
 public:
  explicit StandardNormal(uint64_t seed) : engine_(seed) {}
  double operator()();
  Eigen::Vector3d vector3() {
    const double x = (*this)();
    const double y = (*this)();
    return {x, y, (*this)()};
  }

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0;
};

// When each synthetic sample is taken (sim.imu_sample_time): at its timestamp, or at the midpoint
// of the piece the estimator holds it over (ImuSynthOptions::sample_shift_s = Δt / 2).
enum class ImuSampleTime { kStart, kMidpoint };
inline constexpr EnumNames<ImuSampleTime, 2> kImuSampleTimeNames{
    {{ImuSampleTime::kStart, "start"}, {ImuSampleTime::kMidpoint, "midpoint"}}};
inline const char* toString(ImuSampleTime value) { return nameOf(kImuSampleTimeNames, value); }

struct ImuSynthOptions {
  bool white_noise = true;  // n_g, n_a
  bool bias_walk = true;    // random walk of b_g, b_a
  Eigen::Vector3d initial_bias_gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d initial_bias_accel = Eigen::Vector3d::Zero();
  Eigen::Vector3d gravity_w = Eigen::Vector3d(0, 0, -kGravityMagnitude);
  // Sample k carries the motion at t_k + sample_shift_s (clamped to the trajectory's end). 0: the
  // instant t_k, which the estimator's zero-order hold then holds over [t_k, t_k + Δt), half a
  // sample late (first order in Δt); Δt / 2: the midpoint of that piece (second order;
  // core/sim/imu_hold.h measures both).
  double sample_shift_s = 0;

  // Noise-free measurements (biases stay at their initial values).
  static ImuSynthOptions noiseFree() {
    ImuSynthOptions o;
    o.white_noise = false;
    o.bias_walk = false;
    return o;
  }
};

struct SyntheticImu {
  ImuData imu;
  std::vector<Eigen::Vector3d> bias_gyro;   // b_g,k, one per sample
  std::vector<Eigen::Vector3d> bias_accel;  // b_a,k
};

// Samples at t_start + round(k · 1e9 / rate_hz) ns, k = 0, 1, … while ≤ t_end, where
// [t_start, t_end] = [traj.startTimeNs(), traj.endTimeNs()]. Δt in the noise scaling is the
// nominal 1/rate_hz. Throws InputError for rate_hz <= 0.
SyntheticImu synthesizeImu(const TrajectoryFunction& traj, const ImuNoise& noise,
                           double rate_hz = 200.0, uint64_t seed = 0,
                           const ImuSynthOptions& options = {});

// The samples of imu with t_begin <= t <= t_end.
ImuData clipImu(const ImuData& imu, int64_t t_begin, int64_t t_end);

// The sequence's real IMU recording clipped to [traj.startTimeNs(), traj.endTimeNs()]. Throws
// InputError when the sequence has no real IMU.
ImuData realImuWithin(const Sequence& sequence, const TrajectoryFunction& traj);

}  // namespace marglab
