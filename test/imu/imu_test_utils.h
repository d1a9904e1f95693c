#pragma once
// Helpers of the IMU tests: analytic trajectories with closed-form v_w, a_w, ω_b; true states
// from a trajectory; central differences with an explicit step and their error bound.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>

#include "core/geometry/so3.h"
#include "core/imu/imu_state.h"
#include "core/sim/trajectory_spline.h"

namespace marglab::test {

// R(t) = R_0 Exp(ω t), p(t) = p_0 + v_0 t + ½ a t²: constant body rate and constant world
// acceleration. The zero-order-hold preintegration is exact on it when the frames are at sample
// times (ΔR_k f_k = R_iᵀ (a − g) for every sample); with ω = 0 it is exact for any frame times.
class ConstantRateTrajectory : public TrajectoryFunction {
 public:
  ConstantRateTrajectory(const Eigen::Vector3d& omega_b, const Eigen::Vector3d& a_w,
                         double duration_s)
      : omega_b_(omega_b),
        a_w_(a_w),
        end_ns_(static_cast<int64_t>(std::llround(duration_s * 1e9))) {}
  int64_t startTimeNs() const override { return 0; }
  int64_t endTimeNs() const override { return end_ns_; }
  TrajectorySample evaluate(int64_t t_ns) const override {
    const double t = static_cast<double>(t_ns) * 1e-9;
    TrajectorySample s;
    s.R_w_b = R0() * expSO3<double>(omega_b_ * t);
    s.p_w_b = p0() + v0() * t + 0.5 * t * t * a_w_;
    s.v_w = v0() + t * a_w_;
    s.a_w = a_w_;
    s.omega_b = omega_b_;
    return s;
  }

 private:
  static Eigen::Matrix3d R0() { return expSO3<double>(Eigen::Vector3d(0.3, -0.2, 1.1)); }
  static Eigen::Vector3d p0() { return {1.0, -2.0, 0.5}; }
  static Eigen::Vector3d v0() { return {0.4, 0.7, -0.3}; }
  Eigen::Vector3d omega_b_, a_w_;
  int64_t end_ns_;
};

// A smooth general motion: R(t) = Exp(α(t) u_1) Exp(β(t) u_2), so ω_b = α̇ Exp(β u_2)ᵀ u_1 + β̇ u_2;
// positions of ~1 m at 0.6–1.3 rad/s (|a_w| ≲ 1.5 m/s², |ω_b| ≲ 1.5 rad/s).
class SmoothTrajectory : public TrajectoryFunction {
 public:
  explicit SmoothTrajectory(double duration_s)
      : end_ns_(static_cast<int64_t>(std::llround(duration_s * 1e9))) {}
  int64_t startTimeNs() const override { return 0; }
  int64_t endTimeNs() const override { return end_ns_; }
  TrajectorySample evaluate(int64_t t_ns) const override {
    const double t = static_cast<double>(t_ns) * 1e-9;
    const Eigen::Vector3d u1 = Eigen::Vector3d(0.2, 0.3, 1.0).normalized();
    const Eigen::Vector3d u2 = Eigen::Vector3d(1.0, -0.4, 0.1).normalized();
    const double alpha = 0.8 * std::sin(1.1 * t) + 0.3 * t,
                 alpha_dot = 0.88 * std::cos(1.1 * t) + 0.3;
    const double beta = 0.5 * std::cos(0.7 * t), beta_dot = -0.35 * std::sin(0.7 * t);
    const Eigen::Matrix3d B = expSO3<double>(beta * u2);
    TrajectorySample s;
    s.R_w_b = expSO3<double>(alpha * u1) * B;
    s.omega_b = alpha_dot * B.transpose() * u1 + beta_dot * u2;
    s.p_w_b = {1.2 * std::sin(0.9 * t), 0.8 * std::cos(0.6 * t) + 0.3 * t,
               0.5 * std::sin(1.3 * t + 1.0)};
    s.v_w = {1.08 * std::cos(0.9 * t), -0.48 * std::sin(0.6 * t) + 0.3,
             0.65 * std::cos(1.3 * t + 1.0)};
    s.a_w = {-0.972 * std::sin(0.9 * t), -0.288 * std::cos(0.6 * t),
             -0.845 * std::sin(1.3 * t + 1.0)};
    return s;
  }

 private:
  int64_t end_ns_;
};

// The true state at t_ns with the given biases.
template <typename Scalar>
ImuState<Scalar> trueState(const TrajectoryFunction& traj, int64_t t_ns,
                           const Eigen::Vector3d& b_g = Eigen::Vector3d::Zero(),
                           const Eigen::Vector3d& b_a = Eigen::Vector3d::Zero()) {
  const TrajectorySample s = traj.evaluate(t_ns);
  ImuState<double> x;
  x.t_ns = t_ns;
  x.T_w_i = SE3<double>(s.R_w_b, s.p_w_b);
  x.v_w = s.v_w;
  x.b_g = b_g;
  x.b_a = b_a;
  return x.template cast<Scalar>();
}

// Central differences with step h. For f computed with absolute rounding error ≤ e_f and
// |f'''| ≤ d3, the error is ≤ h² d3/6 + e_f/h; fdStepFor picks the h minimizing it.
template <typename Scalar>
struct FdPlan {
  Scalar h;
  double tol;
};

template <typename Scalar>
FdPlan<Scalar> fdPlan(double rounding_abs, double d3) {
  const double h = std::cbrt(3.0 * rounding_abs / d3);
  return {static_cast<Scalar>(h), h * h * d3 / 6.0 + rounding_abs / h};
}

template <typename Scalar, int M, int N, typename F>
Mat<Scalar, M, N> centralDifferences(const F& f, Scalar h) {
  Mat<Scalar, M, N> J;
  for (int c = 0; c < N; ++c) {
    Vec<Scalar, N> xp = Vec<Scalar, N>::Zero(), xm = Vec<Scalar, N>::Zero();
    xp[c] = h;
    xm[c] = -h;
    J.col(c) = (f(xp) - f(xm)) / (xp[c] - xm[c]);
  }
  return J;
}

}  // namespace marglab::test
