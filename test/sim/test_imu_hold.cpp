// The synthetic IMU's sample time against the estimator's zero-order hold (core/sim/imu_hold.h,
// ImuSynthOptions::sample_shift_s, sim.imu_sample_time).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <vector>

#include "core/data/sequence.h"
#include "core/pipeline/run_config.h"
#include "core/sim/imu_hold.h"
#include "core/sim/imu_synth.h"
#include "core/sim/trajectory_spline.h"

namespace marglab {
namespace {

constexpr int64_t kMs = 1'000'000;

// A shifted sample is the noise-free value at t_k + shift, still stamped t_k; shift 0 leaves the
// stream as it was (the committed runs).
TEST(ImuSampleTime, ShiftedSampleIsTheMotionHalfASampleLater) {
  const Sequence seq = loadSequence("euroc/MH_01_easy", LoadOptions{false});
  const TrajectorySpline spline = TrajectorySpline::fromSequence(seq);
  const TrajectoryWindow window(spline, spline.startTimeNs() + 40'000 * kMs,
                                spline.startTimeNs() + 41'000 * kMs);
  ImuSynthOptions start = ImuSynthOptions::noiseFree(), mid = start;
  mid.sample_shift_s = 0.0025;
  const ImuData a = synthesizeImu(window, ImuNoise{}, 200.0, 0, start).imu;
  const ImuData b = synthesizeImu(window, ImuNoise{}, 200.0, 0, mid).imu;
  ASSERT_EQ(a.t_ns, b.t_ns);
  for (std::size_t k = 0; k + 1 < a.size(); k += 37) {
    const TrajectorySample s = spline.evaluate(a.t_ns[k] + 2'500'000);
    EXPECT_EQ(b.gyro[k], s.omega_b) << k;
    EXPECT_EQ(b.accel[k], s.R_w_b.transpose() * (s.a_w - start.gravity_w)) << k;
    EXPECT_EQ(a.gyro[k], spline.evaluate(a.t_ns[k]).omega_b) << k;
  }
}

double worstRotation(const TrajectoryFunction& window, const std::vector<int64_t>& frames,
                     double rate_hz, double shift_s) {
  double worst = 0;
  for (const ImuHoldInterval& h :
       imuHoldErrors(window, frames, ImuNoise{}, Eigen::Vector3d(0, 0, -kGravityMagnitude), rate_hz,
                     shift_s)) {
    worst = std::max(worst, h.rot_rad);
  }
  return worst;
}

// The hold's rotation error at the true states is first order in the sample period for samples at
// t_k (doubling the rate halves it) and second order for samples at the midpoint (quarters it):
// the convergence order, independent of the kernel's own arithmetic.
TEST(ImuHold, FirstOrderAtTheStartSecondAtTheMidpoint) {
  const Sequence seq = loadSequence("euroc/MH_01_easy", LoadOptions{false});
  const TrajectorySpline spline = TrajectorySpline::fromSequence(seq);
  const int64_t t0 = spline.startTimeNs() + 40'000 * kMs;
  const TrajectoryWindow window(spline, t0, t0 + 3000 * kMs);
  std::vector<int64_t> frames;
  for (int64_t t = t0 + 100 * kMs; t < t0 + 2900 * kMs; t += 50 * kMs) frames.push_back(t);
  const double start_ratio =
      worstRotation(window, frames, 200, 0) / worstRotation(window, frames, 400, 0);
  const double mid_ratio =
      worstRotation(window, frames, 200, 0.5 / 200) / worstRotation(window, frames, 400, 0.5 / 400);
  EXPECT_NEAR(start_ratio, 2.0, 0.4);
  EXPECT_NEAR(mid_ratio, 4.0, 1.0);
  EXPECT_LT(worstRotation(window, frames, 200, 0.5 / 200),
            0.2 * worstRotation(window, frames, 200, 0));
}

// The key reads, names its values and rejects others.
TEST(ImuSampleTime, ConfigKey) {
  RunConfig config;
  EXPECT_EQ(config.sim_imu_sample_time, ImuSampleTime::kStart);
  config.set("sim.imu_sample_time=midpoint", "--set");
  EXPECT_EQ(config.sim_imu_sample_time, ImuSampleTime::kMidpoint);
  EXPECT_ANY_THROW(config.set("sim.imu_sample_time=centre", "--set"));
}

}  // namespace
}  // namespace marglab
