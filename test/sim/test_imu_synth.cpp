// IMU synthesis: noise-free measurements integrate back to the trajectory, the measurement model
// in closed form (static body), determinism, and the noise and bias-walk statistics.

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/sim/imu_synth.h"
#include "core/sim/trajectory_spline.h"
#include "sim/trajectory_test_utils.h"

namespace marglab {
namespace {

constexpr int64_t kT0 = 1'000'000'000'000;
constexpr int64_t k200Hz = 5'000'000;

// A body at rest at a fixed attitude: every measurement is noise + bias + Rᵀ(−g).
class StaticTrajectory : public TrajectoryFunction {
 public:
  StaticTrajectory(const Eigen::Matrix3d& R_w_b, double duration_s)
      : R_w_b_(R_w_b), end_ns_(kT0 + std::llround(duration_s * 1e9)) {}
  int64_t startTimeNs() const override { return kT0; }
  int64_t endTimeNs() const override { return end_ns_; }
  TrajectorySample evaluate(int64_t) const override {
    TrajectorySample s;
    s.R_w_b = R_w_b_;
    return s;
  }

 private:
  Eigen::Matrix3d R_w_b_;
  int64_t end_ns_;
};

// Strapdown integration of (q_w_b, p_w, v_w) with classical RK4 over steps of two IMU periods:
// the stage at the step's midpoint uses the middle sample, so no interpolation is involved.
//   q̇ = ½ q ⊗ (0, ω),  ṗ = v,  v̇ = R(q) a + g_w.
struct StrapdownState {
  Eigen::Vector4d q;  // Eigen coefficient order (x, y, z, w)
  Eigen::Vector3d p, v;
};

StrapdownState derivative(const StrapdownState& x, const Eigen::Vector3d& gyro,
                          const Eigen::Vector3d& accel, const Eigen::Vector3d& g_w) {
  const Eigen::Quaterniond q(x.q(3), x.q(0), x.q(1), x.q(2));
  const Eigen::Quaterniond w(0, gyro.x(), gyro.y(), gyro.z());
  StrapdownState d;
  d.q = 0.5 * (q * w).coeffs();
  d.p = x.v;
  d.v = q.normalized().toRotationMatrix() * accel + g_w;
  return d;
}

StrapdownState axpy(const StrapdownState& x, double a, const StrapdownState& d) {
  return {x.q + a * d.q, x.p + a * d.p, x.v + a * d.v};
}

StrapdownState integrate(const ImuData& imu, std::size_t first, int steps,
                         const TrajectorySample& initial, const Eigen::Vector3d& g_w) {
  StrapdownState x{Eigen::Quaterniond(initial.R_w_b).coeffs(), initial.p_w_b, initial.v_w};
  for (int s = 0; s < steps; ++s) {
    const std::size_t k = first + 2 * static_cast<std::size_t>(s);
    const double H = static_cast<double>(imu.t_ns[k + 2] - imu.t_ns[k]) * 1e-9;
    const StrapdownState k1 = derivative(x, imu.gyro[k], imu.accel[k], g_w);
    const StrapdownState k2 =
        derivative(axpy(x, H / 2, k1), imu.gyro[k + 1], imu.accel[k + 1], g_w);
    const StrapdownState k3 =
        derivative(axpy(x, H / 2, k2), imu.gyro[k + 1], imu.accel[k + 1], g_w);
    const StrapdownState k4 = derivative(axpy(x, H, k3), imu.gyro[k + 2], imu.accel[k + 2], g_w);
    x.q += H / 6 * (k1.q + 2 * k2.q + 2 * k3.q + k4.q);
    x.p += H / 6 * (k1.p + 2 * k2.p + 2 * k3.p + k4.p);
    x.v += H / 6 * (k1.v + 2 * k2.v + 2 * k3.v + k4.v);
    x.q.normalize();
  }
  return x;
}

// Integrates 1 s from the true state at `from_s` and compares with the trajectory.
void expectIntegratesBack(const TrajectoryFunction& traj, const ImuData& imu, double from_s,
                          const Eigen::Vector3d& g_w) {
  const std::size_t first = static_cast<std::size_t>(std::llround(from_s * 200));
  ASSERT_LT(first + 200, imu.size());
  const StrapdownState x = integrate(imu, first, 100, traj.evaluate(imu.t_ns[first]), g_w);
  const TrajectorySample truth = traj.evaluate(imu.t_ns[first + 200]);
  const Eigen::Quaterniond q(x.q(3), x.q(0), x.q(1), x.q(2));
  EXPECT_LT((x.p - truth.p_w_b).norm(), 1e-3) << from_s;
  EXPECT_LT(test::rotationAngle(q.toRotationMatrix(), truth.R_w_b), 0.01 * M_PI / 180) << from_s;
}

TEST(ImuSynth, NoiseFreeIntegratesBackToAnalyticSpline) {
  const TrajectorySplineOptions options = TrajectorySpline::defaultOptions(DatasetKind::kEuroc);
  const TrajectorySpline spline(test::sampleAnalytic(kT0, k200Hz, 2001), options);
  const Eigen::Vector3d g_w(0, 0, -kGravityMagnitude);
  const SyntheticImu imu =
      synthesizeImu(spline, ImuNoise{}, 200.0, 0, ImuSynthOptions::noiseFree());
  for (double from_s : {0.0, 3.3, 8.0}) expectIntegratesBack(spline, imu.imu, from_s, g_w);
}

TEST(ImuSynth, NoiseFreeIntegratesBackOnEurocAndKitti) {
  for (const char* name : {"euroc/MH_01_easy", "kitti/00"}) {
    const Sequence seq = loadSequence(name, LoadOptions{false});
    const TrajectorySpline spline = TrajectorySpline::fromSequence(seq);
    ImuSynthOptions options = ImuSynthOptions::noiseFree();
    options.gravity_w = gravityWorld(seq.kind);
    const SyntheticImu imu = synthesizeImu(spline, seq.imu_noise, 200.0, 0, options);
    for (double from_s : {20.0, 60.0, 100.0, 140.0}) {
      SCOPED_TRACE(name);
      expectIntegratesBack(spline, imu.imu, from_s, options.gravity_w);
    }
  }
}

TEST(ImuSynth, StaticBodyMeasuresGravityAndBias) {
  const Eigen::Matrix3d R = expSO3<double>(Eigen::Vector3d(0.3, -0.5, 1.2));
  const StaticTrajectory traj(R, 1.0);
  ImuSynthOptions options = ImuSynthOptions::noiseFree();
  options.initial_bias_gyro = Eigen::Vector3d(0.01, -0.02, 0.03);
  options.initial_bias_accel = Eigen::Vector3d(-0.1, 0.2, 0.05);
  for (DatasetKind kind : {DatasetKind::kEuroc, DatasetKind::kKitti}) {
    options.gravity_w = gravityWorld(kind);
    const SyntheticImu imu = synthesizeImu(traj, ImuNoise{}, 200.0, 0, options);
    ASSERT_EQ(imu.imu.size(), 201u);
    const Eigen::Vector3d up_w = -options.gravity_w;
    for (std::size_t k = 0; k < imu.imu.size(); ++k) {
      EXPECT_EQ(imu.imu.t_ns[k], kT0 + static_cast<int64_t>(k) * k200Hz);
      EXPECT_LT((imu.imu.gyro[k] - options.initial_bias_gyro).norm(), 1e-15);
      EXPECT_LT((imu.imu.accel[k] - R.transpose() * up_w - options.initial_bias_accel).norm(),
                1e-14);
      EXPECT_EQ(imu.bias_gyro[k], options.initial_bias_gyro);
      EXPECT_EQ(imu.bias_accel[k], options.initial_bias_accel);
    }
  }
  EXPECT_EQ(gravityWorld(DatasetKind::kEuroc), Eigen::Vector3d(0, 0, -9.81));
  EXPECT_EQ(gravityWorld(DatasetKind::kKitti), Eigen::Vector3d(0, 9.81, 0));
}

TEST(ImuSynth, DeterministicForASeed) {
  const StaticTrajectory traj(Eigen::Matrix3d::Identity(), 2.0);
  const SyntheticImu a = synthesizeImu(traj, ImuNoise{}, 200.0, 42);
  const SyntheticImu b = synthesizeImu(traj, ImuNoise{}, 200.0, 42);
  const SyntheticImu c = synthesizeImu(traj, ImuNoise{}, 200.0, 43);
  ASSERT_EQ(a.imu.size(), b.imu.size());
  std::size_t differ = 0;
  for (std::size_t k = 0; k < a.imu.size(); ++k) {
    EXPECT_EQ(a.imu.gyro[k], b.imu.gyro[k]);
    EXPECT_EQ(a.imu.accel[k], b.imu.accel[k]);
    EXPECT_EQ(a.bias_accel[k], b.bias_accel[k]);
    differ += a.imu.gyro[k] != c.imu.gyro[k] && a.imu.accel[k] != c.imu.accel[k];
  }
  EXPECT_EQ(differ, a.imu.size());
}

// Sample moments of N draws: mean ~ N(0, 1/N), variance ~ N(1, 2/N), fourth moment ~ N(3, 96/N);
// 5 standard errors.
TEST(ImuSynth, StandardNormalMoments) {
  StandardNormal normal(5);
  const int n = 1'000'000;
  double m1 = 0, m2 = 0, m4 = 0;
  for (int i = 0; i < n; ++i) {
    const double z = normal();
    m1 += z;
    m2 += z * z;
    m4 += z * z * z * z;
  }
  m1 /= n;
  m2 /= n;
  m4 /= n;
  EXPECT_LT(std::abs(m1), 5 / std::sqrt(n));
  EXPECT_LT(std::abs(m2 - 1), 5 * std::sqrt(2.0 / n));
  EXPECT_LT(std::abs(m4 - 3), 5 * std::sqrt(96.0 / n));
}

// Sample standard deviation of N zero-mean normal values: relative standard error 1/√(2N).
void expectStd(const std::vector<double>& x, double sigma) {
  double sq = 0, mean = 0;
  for (double v : x) {
    mean += v;
    sq += v * v;
  }
  const double n = static_cast<double>(x.size());
  mean /= n;
  EXPECT_LT(std::abs(mean), 5 * sigma / std::sqrt(n));
  EXPECT_NEAR(std::sqrt(sq / n) / sigma, 1.0, 5 / std::sqrt(2 * n));
}

TEST(ImuSynth, WhiteNoiseStatistics) {
  const Eigen::Matrix3d R = expSO3<double>(Eigen::Vector3d(0.1, 0.2, -0.3));
  const StaticTrajectory traj(R, 100.0);
  ImuSynthOptions options;
  options.bias_walk = false;
  const ImuNoise noise;  // EuRoC densities
  for (double rate : {200.0, 400.0}) {
    const SyntheticImu imu = synthesizeImu(traj, noise, rate, 11, options);
    std::vector<double> ng, na;
    const Eigen::Vector3d f = R.transpose() * -options.gravity_w;
    for (std::size_t k = 0; k < imu.imu.size(); ++k) {
      for (int i = 0; i < 3; ++i) {
        ng.push_back(imu.imu.gyro[k](i));
        na.push_back(imu.imu.accel[k](i) - f(i));
      }
    }
    SCOPED_TRACE(rate);
    expectStd(ng, noise.gyro_noise_density * std::sqrt(rate));
    expectStd(na, noise.accel_noise_density * std::sqrt(rate));
  }
}

TEST(ImuSynth, BiasRandomWalkStatistics) {
  const StaticTrajectory traj(Eigen::Matrix3d::Identity(), 100.0);
  ImuSynthOptions options;
  options.white_noise = false;
  options.initial_bias_gyro = Eigen::Vector3d(1e-3, 2e-3, -1e-3);
  const ImuNoise noise;
  const SyntheticImu imu = synthesizeImu(traj, noise, 200.0, 3, options);
  EXPECT_EQ(imu.bias_gyro.front(), options.initial_bias_gyro);
  std::vector<double> dg, da;
  const Eigen::Vector3d f = -options.gravity_w;
  for (std::size_t k = 0; k < imu.imu.size(); ++k) {
    // Without white noise the measurement is truth + the returned bias.
    EXPECT_LT((imu.imu.gyro[k] - imu.bias_gyro[k]).norm(), 1e-15);
    EXPECT_LT((imu.imu.accel[k] - f - imu.bias_accel[k]).norm(), 1e-13);
    if (k == 0) continue;
    for (int i = 0; i < 3; ++i) {
      dg.push_back(imu.bias_gyro[k](i) - imu.bias_gyro[k - 1](i));
      da.push_back(imu.bias_accel[k](i) - imu.bias_accel[k - 1](i));
    }
  }
  expectStd(dg, noise.gyro_random_walk * std::sqrt(1.0 / 200));
  expectStd(da, noise.accel_random_walk * std::sqrt(1.0 / 200));
}

TEST(ImuSynth, RealImuClippedToTrajectory) {
  const Sequence v1 = loadSequence("euroc/V1_01_easy");
  const TrajectorySpline spline = TrajectorySpline::fromSequence(v1);
  const ImuData real = realImuWithin(v1, spline);
  ASSERT_FALSE(real.empty());
  EXPECT_GE(real.t_ns.front(), spline.startTimeNs());
  EXPECT_LE(real.t_ns.back(), spline.endTimeNs());
  EXPECT_LT(real.size(), v1.imu->size());
  const double rate = static_cast<double>(real.size() - 1) /
                      (static_cast<double>(real.t_ns.back() - real.t_ns.front()) * 1e-9);
  EXPECT_NEAR(rate, 200.0, 2.0);

  const Sequence mh = loadSequence("euroc/MH_01_easy");
  EXPECT_THROW(realImuWithin(mh, TrajectorySpline::fromSequence(mh)), InputError);
  EXPECT_THROW(synthesizeImu(spline, ImuNoise{}, 0.0), InputError);
}

}  // namespace
}  // namespace marglab
