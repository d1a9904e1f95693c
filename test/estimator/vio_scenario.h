#pragma once
// A short VIO scenario for the estimator tests: EuRoC MH_01's trajectory with noise-free simulated
// stereo tracks and a noise-free synthetic IMU.

#include <cstdint>
#include <vector>

#include "core/data/sequence.h"
#include "core/estimator/estimator.h"
#include "core/pipeline/run.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/imu_synth.h"
#include "core/sim/trajectory_spline.h"

namespace marglab::test {

// The estimator without the gauge diagnostics' shadow prior (the tests that need only its
// estimate).
inline constexpr EstimatorReporting kWithoutShadowPrior{false};

// MH_01 from t_begin_s for duration_s, cameras at 10 Hz (every other EuRoC frame, to keep the
// test fast), tracks and IMU without noise or outliers.

struct VioScenario {
  Sequence sequence;
  TrajectorySpline spline;
  TrackStream stream;
  ImuSetup imu;

  // imu_rate_hz: the synthetic IMU's discretization is what keeps noise-free measurements from
  // being exactly consistent (a few mm over 60 s at 1 kHz).
  VioScenario(double t_begin_s, double duration_s, double imu_rate_hz = 1000.0)
      : sequence(loadSequence("euroc/MH_01_easy")),
        spline(TrajectorySpline::fromSequence(sequence)) {
    const int64_t t0 = spline.startTimeNs() + static_cast<int64_t>(t_begin_s * 1e9);
    const int64_t t1 = t0 + static_cast<int64_t>(duration_s * 1e9);
    std::vector<int64_t> cams;
    for (size_t k = 0; k < sequence.cam_t_ns.size(); k += 2) {
      if (sequence.cam_t_ns[k] >= t0 && sequence.cam_t_ns[k] <= t1) {
        cams.push_back(sequence.cam_t_ns[k]);
      }
    }
    sequence.cam_t_ns = cams;
    SimulationOptions options = defaultSimulationOptions(sequence, 3);
    options.tracker.noise = false;
    options.tracker.outliers = false;
    stream = simulateSequence(sequence, spline, options);
    imu.noise = sequence.imu_noise;
    imu.g_w = gravityWorld(DatasetKind::kEuroc);
    ImuSynthOptions synth = ImuSynthOptions::noiseFree();
    synth.gravity_w = imu.g_w;
    imu.imu = synthesizeImu(spline, imu.noise, imu_rate_hz, 5, synth).imu;
    imu.sample_period_s = 1.0 / imu_rate_hz;
    const TrajectorySample s = spline.evaluate(stream.frames.front().t_ns);
    imu.initial.t_ns = stream.frames.front().t_ns;
    imu.initial.T_w_i = SE3<double>(s.R_w_b, s.p_w_b);
    imu.initial.v_w = s.v_w;
  }
  Eigen::Vector3d truePosition(int64_t t_ns) const { return spline.evaluate(t_ns).p_w_b; }
  template <typename Scalar>
  SlidingWindowEstimator<Scalar> estimator(const Variant& variant,
                                           const EstimatorSettings& config = {},
                                           EstimatorReporting reporting = {}) const {
    EstimatorSettings c = config;
    if (c.min_frames_after_kf < 0) c.min_frames_after_kf = 3;  // 5 at 20 Hz
    return SlidingWindowEstimator<Scalar>(c, variant, rigFromCalib(sequence.calib),
                                          imu.initial.T_w_i, imu, reporting);
  }
};

}  // namespace marglab::test
