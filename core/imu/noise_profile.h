#pragma once
// IMU noise profiles: which continuous-time densities (ImuNoise, core/data/types.h) a VIO run uses,
// both for the synthetic IMU (core/sim/imu_synth.h) and for the estimator's IMU weights
// (preintegration covariance, bias random-walk factor). docs/design.md §5.
//
//   kalibr  the sequence's own densities: the Kalibr/OpenVINS imu chain shipped in
//           datasets/<kind>/calib/openvins_kalibr_imu_chain.yaml, or a user folder's
//           imu0/sensor.yaml (EuRoC: σ_g = 1.6968e-4, σ_rw,g = 1.9393e-5, σ_a = 2.0e-3,
//           σ_rw,a = 3.0e-3). The default, and the only profile before issue #19.
//   basalt  the densities of Basalt's calibration files, which the paper's estimator (Demmel et
//           al., ICCV 2021) was run with: datasets/<kind>/calib/basalt_<…>_ds_calib.json
//           (EuRoC and TUM-VI: σ_g = 2.82e-4, σ_rw,g = 1e-4, σ_a = 0.016, σ_rw,a = 1e-3).
//
// Basalt names the densities *_noise_std and *_bias_std, but uses them as continuous densities
// exactly as Kalibr does: the discrete sample noise is σ √rate and the bias random-walk weight over
// Δt is 1 / (σ_rw √Δt) (basalt/calibration.hpp, dicrete_time_*_noise_std). So the four values map
// one to one onto ImuNoise.

#include <string>

#include "core/common/enum_names.h"
#include "core/data/types.h"

namespace marglab {

enum class ImuNoiseProfile { kKalibr, kBasalt };
inline constexpr EnumNames<ImuNoiseProfile, 2> kImuNoiseProfileNames{
    {{ImuNoiseProfile::kKalibr, "kalibr"}, {ImuNoiseProfile::kBasalt, "basalt"}}};
inline const char* toString(ImuNoiseProfile value) { return nameOf(kImuNoiseProfileNames, value); }
inline bool parseImuNoiseProfile(const std::string& text, ImuNoiseProfile* value) {
  return parseName(kImuNoiseProfileNames, text, value);
}

// The four IMU densities of a Basalt calibration (cereal JSON: "accel_noise_std",
// "gyro_noise_std", "accel_bias_std", "gyro_bias_std", each a list of three per-axis values).
// marglab's noise model is isotropic, so the three values must be equal and > 0. Not a general
// JSON reader: each key must appear exactly once. Throws InputError(path, line, "expected …").
ImuNoise readBasaltImuNoise(const std::string& path);

// The shipped Basalt calibration of a dataset kind
// (datasets/euroc/calib/basalt_euroc_ds_calib.json,
// datasets/tumvi/calib/basalt_tumvi_512_ds_calib.json). Throws InputError for KITTI (no IMU).
std::string basaltCalibrationFile(DatasetKind kind);

// The densities of `profile` for a loaded sequence: kalibr → sequence.imu_noise (unchanged),
// basalt → the shipped Basalt calibration of the sequence's dataset kind.
ImuNoise profileImuNoise(const Sequence& sequence, ImuNoiseProfile profile);

}  // namespace marglab
