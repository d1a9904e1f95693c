// IMU factor against independent computations: central differences of the residual w.r.t. every
// ⊞ component of both states (left rotation perturbation), the whitening against Σ, the bias
// random walk, and predictState against the true trajectory and against the residual.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <random>
#include <vector>

#include "core/common/error.h"
#include "core/imu/imu_factor.h"
#include "core/imu/preintegration.h"
#include "core/sim/imu_synth.h"
#include "test/geometry/geometry_test_utils.h"
#include "test/imu/imu_test_utils.h"

namespace marglab::test {
namespace {

constexpr double kRateHz = 200.0;
constexpr double kPeriodS = 1.0 / kRateHz;
constexpr int64_t kMs = 1000000;
const Eigen::Vector3d kGravity(0, 0, -kGravityMagnitude);

template <typename Scalar>
class ImuFactorTyped : public ::testing::Test {};
TYPED_TEST_SUITE(ImuFactorTyped, ScalarTypes, ScalarNames);

// A noisy preintegration over [t_i, t_j] of the smooth motion, linearized at (bg_lin, ba_lin).
template <typename S>
ImuPreintegration<S> noisyPreintegration(int64_t t_i, int64_t t_j, const Vec3<S>& bg_lin,
                                         const Vec3<S>& ba_lin) {
  const SmoothTrajectory traj(1.0);
  const ImuData imu = synthesizeImu(traj, ImuNoise{}, kRateHz, 17).imu;
  return preintegrate<S>(imu, t_i, t_j, bg_lin, ba_lin,
                         ImuSampleNoise<S>::fromDensities(ImuNoise{}, kPeriodS));
}

// A random 15-dof increment: 0.1 m, 0.2 rad, 0.2 m/s, 0.02 rad/s, 0.2 m/s² scale.
template <typename S>
Vec<S, 15> randomIncrement(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Vec<double, 15> d;
  for (int k = 0; k < 15; ++k) d[k] = n(rng);
  d.segment<3>(ImuStateIndex::kPos) *= 0.1;
  d.segment<3>(ImuStateIndex::kRot) *= 0.2;
  d.segment<3>(ImuStateIndex::kVel) *= 0.2;
  d.segment<3>(ImuStateIndex::kBiasGyro) *= 0.02;
  d.segment<3>(ImuStateIndex::kBiasAccel) *= 0.2;
  return d.cast<S>();
}

// ∂r/∂[δ_i | δ_j] (9×30) against central differences of r(s_i ⊞ δ_i, s_j ⊞ δ_j), at states
// perturbed off the truth (r ≠ 0, |r_R| up to ~0.5 rad) and biases off the linearization point
// (the Jr(J_R δb_g) term is active). Rounding of one evaluation ≤ 16 ulps of the largest
// intermediate (|p| ≲ 5 m); third derivatives bounded by the same scale.
TYPED_TEST(ImuFactorTyped, ResidualJacobiansMatchCentralDifferences) {
  using S = TypeParam;
  const SmoothTrajectory traj(1.0);
  const int64_t t_i = 201234567, t_j = 451234567;
  const Vec3<S> bg_lin(S(0.01), S(-0.02), S(0.005)), ba_lin(S(0.05), S(0.1), S(-0.1));
  const ImuFactor<S> factor(noisyPreintegration<S>(t_i, t_j, bg_lin, ba_lin), kGravity.cast<S>());
  const double scale = 5.0;
  const FdPlan<S> plan = fdPlan<S>(16 * kEps<S> * scale, scale);
  std::mt19937 rng(23);
  for (int trial = 0; trial < 8; ++trial) {
    const ImuState<S> s_i = boxPlus(trueState<S>(traj, t_i), randomIncrement<S>(rng));
    const ImuState<S> s_j = boxPlus(trueState<S>(traj, t_j), randomIncrement<S>(rng));
    Mat<S, 9, 30> J;
    factor.residual(s_i, s_j, &J);
    const auto f = [&](const Vec<S, 30>& d) -> Vec<S, 9> {
      return factor.residual(boxPlus(s_i, Vec<S, 15>(d.template head<15>())),
                             boxPlus(s_j, Vec<S, 15>(d.template tail<15>())));
    };
    const Mat<S, 9, 30> J_fd = centralDifferences<S, 9, 30>(f, plan.h);
    EXPECT_TRUE(matricesNear(J, J_fd, plan.tol)) << "trial " << trial;
    // The biases of state j do not enter.
    EXPECT_TRUE(J.template middleCols<6>(15 + ImuStateIndex::kBiasGyro).isZero());
  }
}

// W = L⁻¹ is lower triangular with W Σ Wᵀ = I; the whitened residual and Jacobian are W r, W J.
TYPED_TEST(ImuFactorTyped, WhitenedResidualUsesSqrtInformation) {
  using S = TypeParam;
  const SmoothTrajectory traj(1.0);
  const int64_t t_i = 300 * kMs, t_j = 350 * kMs;
  const ImuFactor<S> factor(noisyPreintegration<S>(t_i, t_j, Vec3<S>::Zero(), Vec3<S>::Zero()),
                            kGravity.cast<S>());
  const Mat<S, 9, 9>& W = factor.sqrtInformation();
  EXPECT_TRUE(W.isLowerTriangular());
  const Eigen::Matrix<double, 9, 9> Wd = W.template cast<double>();
  const Eigen::Matrix<double, 9, 9> I =
      Wd * factor.preintegration().covariance().template cast<double>() * Wd.transpose();
  // W is computed in double and rounded to S (W + E, |E| ≤ ε_S |W|): W Σ Wᵀ − I ≈ E L + (E L)ᵀ
  // with L = W⁻¹, bounded by 2 ε_S ‖W‖ ‖L‖ (Frobenius), plus the double rounding.
  const double kappa = Wd.norm() * Wd.inverse().norm();
  EXPECT_TRUE(matricesNear(I, Eigen::Matrix<double, 9, 9>::Identity(),
                           2 * kEps<S> * kappa + 64 * kEps<double> * kappa));

  std::mt19937 rng(5);
  const ImuState<S> s_i = boxPlus(trueState<S>(traj, t_i), randomIncrement<S>(rng));
  const ImuState<S> s_j = boxPlus(trueState<S>(traj, t_j), randomIncrement<S>(rng));
  Mat<S, 9, 30> J, J_w;
  const Vec<S, 9> r = factor.residual(s_i, s_j, &J);
  const Vec<S, 9> r_w = factor.whitenedResidual(s_i, s_j, &J_w);
  const Vec<S, 9> r_ref = W * r;
  const Mat<S, 9, 30> J_ref = W * J;
  EXPECT_TRUE(matricesNear(r_w, r_ref, 16 * kEps<S> * r_ref.cwiseAbs().maxCoeff()));
  EXPECT_TRUE(matricesNear(J_w, J_ref, 16 * kEps<S> * J_ref.cwiseAbs().maxCoeff()));
}

TEST(ImuFactor, ZeroDurationIsRejected) {
  const ImuData imu = synthesizeImu(SmoothTrajectory(0.1), ImuNoise{}, kRateHz, 0).imu;
  const auto noise = ImuSampleNoise<double>::fromDensities(ImuNoise{}, kPeriodS);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  EXPECT_THROW(
      ImuFactor<double>(preintegrate<double>(imu, 50 * kMs, 50 * kMs, zero, zero, noise), kGravity),
      InputError);
}

// The message names the frames' times (issue #18: "IMU factor: …" named no frame).
TEST(ImuFactor, FailureNamesTheFrameTimes) {
  ImuData imu = synthesizeImu(SmoothTrajectory(0.1), ImuNoise{}, kRateHz, 0).imu;
  imu.accel[3].x() = 1e300;  // overflows the covariance propagation: not positive definite
  const auto noise = ImuSampleNoise<double>::fromDensities(ImuNoise{}, kPeriodS);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  try {
    ImuFactor<double>(preintegrate<double>(imu, 0, 50 * kMs, zero, zero, noise), kGravity);
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("IMU factor between the frames at t = 0 ns and t = "
                                          "50000000 ns (0.05 s): the preintegrated covariance is "
                                          "not positive definite",
                                          0),
              0u)
        << e.what();
  }
}

// r = [(b_g,j − b_g,i); (b_a,j − b_a,i)] / (σ_rw √Δt), and its (linear) Jacobian against central
// differences.
TYPED_TEST(ImuFactorTyped, BiasRandomWalkResidualAndJacobian) {
  using S = TypeParam;
  const ImuNoise noise;
  std::mt19937 rng(9);
  const SmoothTrajectory traj(1.0);
  const ImuState<S> s_i = boxPlus(trueState<S>(traj, 100 * kMs), randomIncrement<S>(rng));
  const ImuState<S> s_j = boxPlus(trueState<S>(traj, 150 * kMs), randomIncrement<S>(rng));
  const S dt = S(0.05);
  Mat<S, 6, 30> J;
  const Vec<S, 6> r = biasRandomWalkResidual(s_i, s_j, dt, noise, &J);
  const double w_g = 1.0 / (noise.gyro_random_walk * std::sqrt(0.05));
  const double w_a = 1.0 / (noise.accel_random_walk * std::sqrt(0.05));
  Vec<double, 6> r_ref;
  r_ref << w_g * (s_j.b_g - s_i.b_g).template cast<double>(),
      w_a * (s_j.b_a - s_i.b_a).template cast<double>();
  EXPECT_TRUE(matricesNear(r, r_ref, 8 * kEps<S> * r_ref.cwiseAbs().maxCoeff()));

  const auto f = [&](const Vec<S, 30>& d) -> Vec<S, 6> {
    return biasRandomWalkResidual(boxPlus(s_i, Vec<S, 15>(d.template head<15>())),
                                  boxPlus(s_j, Vec<S, 15>(d.template tail<15>())), dt, noise);
  };
  // Linear: no truncation error; rounding of b ± h (|b| ≲ 0.5) times the weight, over 2h.
  const S h = S(1e-2);
  const Mat<S, 6, 30> J_fd = centralDifferences<S, 6, 30>(f, h);
  const double w_max = std::max(w_g, w_a);
  EXPECT_TRUE(matricesNear(J, J_fd, 4 * kEps<S> * w_max * 0.5 / double(h) + 8 * kEps<S> * w_max));
}

// predictState on noise-free data reproduces the true state at t_j: exactly (< 1e-9) on the
// constant-rate trajectory where the hold is exact (biases at the linearization point), and to
// the discretization error on the smooth motion.
TEST(ImuFactor, PredictStateReproducesTheTrueState) {
  const ConstantRateTrajectory traj(Eigen::Vector3d(-0.4, 0.6, 0.5),
                                    Eigen::Vector3d(-0.3, 0.8, 0.4), 2.0);
  const Eigen::Vector3d bg(0.01, 0.03, -0.02), ba(-0.1, 0.15, 0.2);
  ImuSynthOptions opts = ImuSynthOptions::noiseFree();
  opts.initial_bias_gyro = bg;
  opts.initial_bias_accel = ba;
  const ImuData imu = synthesizeImu(traj, ImuNoise{}, kRateHz, 0, opts).imu;
  const auto noise = ImuSampleNoise<double>::fromDensities(ImuNoise{}, kPeriodS);
  const int64_t t_i = 200 * kMs, t_j = 1200 * kMs;
  const ImuState<double> s_i = trueState<double>(traj, t_i, bg, ba);
  const ImuState<double> truth = trueState<double>(traj, t_j, bg, ba);
  const ImuState<double> pred =
      predictState(s_i, preintegrate<double>(imu, t_i, t_j, bg, ba, noise), kGravity);
  EXPECT_EQ(pred.t_ns, t_j);
  EXPECT_LT(boxMinus(pred, truth).cwiseAbs().maxCoeff(), 1e-9) << boxMinus(pred, truth).transpose();
}

// For any state i and any biases (bias correction active), the residual between s_i and its
// prediction is zero up to rounding: predictState inverts the residual.
TYPED_TEST(ImuFactorTyped, ResidualOfPredictionIsZero) {
  using S = TypeParam;
  const SmoothTrajectory traj(1.0);
  const int64_t t_i = 400 * kMs, t_j = 650 * kMs;
  const ImuFactor<S> factor(
      noisyPreintegration<S>(t_i, t_j, Vec3<S>(S(0.01), S(0), S(0)), Vec3<S>(S(0), S(0.1), S(0))),
      kGravity.cast<S>());
  std::mt19937 rng(31);
  for (int trial = 0; trial < 5; ++trial) {
    const ImuState<S> s_i = boxPlus(trueState<S>(traj, t_i), randomIncrement<S>(rng));
    const ImuState<S> s_j = predictState(s_i, factor.preintegration(), factor.gravity());
    const Vec<S, 9> r = factor.residual(s_i, s_j);
    EXPECT_LT(r.cwiseAbs().maxCoeff(), 64 * kEps<S> * 5.0) << r.transpose();
  }
}

}  // namespace
}  // namespace marglab::test
