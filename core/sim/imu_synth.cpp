#include "core/sim/imu_synth.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/common/error.h"

namespace marglab {

Eigen::Vector3d gravityWorld(DatasetKind kind) {
  if (kind == DatasetKind::kKitti) return {0, kGravityMagnitude, 0};
  return {0, 0, -kGravityMagnitude};
}

double StandardNormal::operator()() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  // 53-bit uniforms: u1 ∈ (0, 1] keeps the logarithm finite, u2 ∈ [0, 1).
  constexpr double kScale = 1.0 / 9007199254740992.0;  // 2⁻⁵³
  const double u1 = static_cast<double>((engine_() >> 11) + 1) * kScale;
  const double u2 = static_cast<double>(engine_() >> 11) * kScale;
  const double radius = std::sqrt(-2.0 * std::log(u1));
  const double angle = 2.0 * M_PI * u2;
  spare_ = radius * std::sin(angle);
  has_spare_ = true;
  return radius * std::cos(angle);
}

SyntheticImu synthesizeImu(const TrajectoryFunction& traj, const ImuNoise& noise, double rate_hz,
                           uint64_t seed, const ImuSynthOptions& options) {
  if (!(rate_hz > 0)) {
    throw InputError("", 0, "IMU synthesis: rate must be > 0, got " + std::to_string(rate_hz));
  }
  const double dt = 1.0 / rate_hz;
  const double sigma_g = noise.gyro_noise_density / std::sqrt(dt);
  const double sigma_a = noise.accel_noise_density / std::sqrt(dt);
  const double walk_g = noise.gyro_random_walk * std::sqrt(dt);
  const double walk_a = noise.accel_random_walk * std::sqrt(dt);

  const int64_t t_start = traj.startTimeNs();
  const int64_t t_end = traj.endTimeNs();
  const double period_ns = 1e9 / rate_hz;
  StandardNormal normal(seed);
  Eigen::Vector3d bg = options.initial_bias_gyro;
  Eigen::Vector3d ba = options.initial_bias_accel;

  SyntheticImu out;
  const auto expected =
      static_cast<std::size_t>(static_cast<double>(t_end - t_start) / period_ns) + 1;
  out.imu.t_ns.reserve(expected);
  out.imu.gyro.reserve(expected);
  out.imu.accel.reserve(expected);
  out.bias_gyro.reserve(expected);
  out.bias_accel.reserve(expected);
  const int64_t shift_ns = std::llround(options.sample_shift_s * 1e9);
  for (int64_t k = 0;; ++k) {
    const int64_t t = t_start + std::llround(static_cast<double>(k) * period_ns);
    if (t > t_end) break;
    const TrajectorySample s = traj.evaluate(std::min(t + shift_ns, t_end));
    Eigen::Vector3d gyro = s.omega_b + bg;
    Eigen::Vector3d accel = s.R_w_b.transpose() * (s.a_w - options.gravity_w) + ba;
    if (options.white_noise) {
      gyro += sigma_g * normal.vector3();
      accel += sigma_a * normal.vector3();
    }
    out.imu.t_ns.push_back(t);
    out.imu.gyro.push_back(gyro);
    out.imu.accel.push_back(accel);
    out.bias_gyro.push_back(bg);
    out.bias_accel.push_back(ba);
    if (options.bias_walk) {
      bg += walk_g * normal.vector3();
      ba += walk_a * normal.vector3();
    }
  }
  return out;
}

ImuData clipImu(const ImuData& imu, int64_t t_begin, int64_t t_end) {
  ImuData out;
  for (std::size_t k = 0; k < imu.size(); ++k) {
    if (imu.t_ns[k] < t_begin || imu.t_ns[k] > t_end) continue;
    out.t_ns.push_back(imu.t_ns[k]);
    out.gyro.push_back(imu.gyro[k]);
    out.accel.push_back(imu.accel[k]);
  }
  return out;
}

ImuData realImuWithin(const Sequence& sequence, const TrajectoryFunction& traj) {
  if (!sequence.imu) {
    throw InputError(sequence.directory, 0,
                     sequence.name + " has no real IMU recording (use the synthetic IMU)");
  }
  return clipImu(*sequence.imu, traj.startTimeNs(), traj.endTimeNs());
}

}  // namespace marglab
