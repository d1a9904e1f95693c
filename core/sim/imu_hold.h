#pragma once
// How well the estimator's IMU model fits the simulator's IMU (issue #40 §1): the noise-free
// synthetic IMU, preintegrated over each camera-frame interval with the estimator's zero-order hold
// (core/imu/preintegration.h), against the true states of the trajectory spline. The residual
// r = [r_p; r_R; r_v] of ImuFactor at the true states is then the hold's discretization error
// alone; whitened by the preintegrated noise of the run's densities, χ² = |W r|² says how many
// noise sigmas the model is off (a consistent model: χ² ≪ 9, the noise's own expectation).
//
// The synthetic IMU holds each sample, taken at t_k, on [t_k, t_k + Δt): it lags the motion by
// half a sample, an error first order in Δt that grows with the angular acceleration and the jerk.
// sample_shift_s evaluates the samples at t_k + shift instead (ImuSynthOptions::sample_shift_s;
// Δt / 2: the midpoint of each held piece, second order), to show how much of the error is that
// lag.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "core/data/types.h"
#include "core/sim/trajectory_spline.h"

namespace marglab {

struct ImuHoldInterval {
  int64_t t_i_ns = 0, t_j_ns = 0;
  double rot_rad = 0, vel_mps = 0, pos_m = 0;  // |r_R|, |r_v|, |r_p|
  double chi2 = 0;                             // |W r|² with the noise of `noise`
};

// Every interval between consecutive frame_t_ns (sorted) inside the trajectory's span, the IMU
// synthesized noise-free at rate_hz from the trajectory's start. Throws InputError for rate_hz <= 0.
std::vector<ImuHoldInterval> imuHoldErrors(const TrajectoryFunction& trajectory,
                                           const std::vector<int64_t>& frame_t_ns,
                                           const ImuNoise& noise, const Eigen::Vector3d& g_w,
                                           double rate_hz = 200.0, double sample_shift_s = 0.0);

}  // namespace marglab
