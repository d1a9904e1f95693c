#include "core/imu/preintegration.h"

#include <algorithm>
#include <iterator>
#include <string>

#include "core/common/error.h"
#include "core/common/scalar.h"
#include "core/geometry/so3.h"

namespace marglab {

template <typename Scalar>
ImuPreintegration<Scalar>::ImuPreintegration(int64_t t_start_ns, const Vec3T& bias_gyro_lin,
                                             const Vec3T& bias_accel_lin)
    : t_start_ns_(t_start_ns), bias_gyro_lin_(bias_gyro_lin), bias_accel_lin_(bias_accel_lin) {}

template <typename Scalar>
void ImuPreintegration<Scalar>::integrate(int64_t dt_ns, const Vec3T& gyro, const Vec3T& accel,
                                          const ImuSampleNoise<Scalar>& noise) {
  const Scalar dt = static_cast<Scalar>(static_cast<double>(dt_ns) * 1e-9);
  const Scalar dt2 = dt * dt;
  const Vec3T omega = gyro - bias_gyro_lin_;
  const Vec3T f = accel - bias_accel_lin_;
  const Vec3T phi = omega * dt;
  const Mat3T R = delta_q_.toRotationMatrix();
  const Mat3T dR = expSO3(phi);
  const Mat3T Jr = rightJacobianSO3(phi);
  const Vec3T Rf = R * f;
  const Mat3T Rf_hat = R * hat(f);

  // Covariance: Σ ← A Σ Aᵀ + σ_g,d² B_g B_gᵀ + σ_a,d² B_a B_aᵀ (order p, R, v).
  constexpr int P = PreintIndex::kPos, O = PreintIndex::kRot, V = PreintIndex::kVel;
  Mat9T A = Mat9T::Identity();
  A.template block<3, 3>(P, O) = Scalar(-0.5) * dt2 * Rf_hat;
  A.template block<3, 3>(P, V) = dt * Mat3T::Identity();
  A.template block<3, 3>(O, O) = dR.transpose();
  A.template block<3, 3>(V, O) = -dt * Rf_hat;
  cov_ = (A * cov_ * A.transpose()).eval();
  cov_.template block<3, 3>(O, O) += (noise.gyro_var * dt2) * (Jr * Jr.transpose());
  const Scalar sa = noise.accel_var;
  cov_.template block<3, 3>(P, P).diagonal().array() += sa * Scalar(0.25) * dt2 * dt2;
  cov_.template block<3, 3>(P, V).diagonal().array() += sa * Scalar(0.5) * dt2 * dt;
  cov_.template block<3, 3>(V, P).diagonal().array() += sa * Scalar(0.5) * dt2 * dt;
  cov_.template block<3, 3>(V, V).diagonal().array() += sa * dt2;

  // Bias Jacobians, from the values before this piece.
  d_p_d_bg_ += dt * d_v_d_bg_ - Scalar(0.5) * dt2 * Rf_hat * d_R_d_bg_;
  d_p_d_ba_ += dt * d_v_d_ba_ - Scalar(0.5) * dt2 * R;
  d_v_d_bg_ -= dt * Rf_hat * d_R_d_bg_;
  d_v_d_ba_ -= dt * R;
  d_R_d_bg_ = (dR.transpose() * d_R_d_bg_ - dt * Jr).eval();

  // Deltas.
  delta_p_ += dt * delta_v_ + Scalar(0.5) * dt2 * Rf;
  delta_v_ += dt * Rf;
  delta_q_ = delta_q_ * expSO3Quaternion(phi);
  delta_q_.normalize();
  dt_ns_ += dt_ns;
}

template <typename Scalar>
void ImuPreintegration<Scalar>::integrateUntil(const ImuData& imu, int64_t t_end_ns,
                                               const ImuSampleNoise<Scalar>& noise) {
  if (imu.empty()) throw InputError("", 0, "IMU preintegration: no IMU samples");
  int64_t t = endTimeNs();
  if (t_end_ns < t) {
    throw InputError("", 0,
                     "IMU preintegration: end time " + std::to_string(t_end_ns) +
                         " ns precedes the current end " + std::to_string(t) + " ns");
  }
  // The sample in force at t: the last one with t_k <= t, or the first one before the data.
  const auto after = std::upper_bound(imu.t_ns.begin(), imu.t_ns.end(), t);
  std::size_t k = after == imu.t_ns.begin()
                      ? 0
                      : static_cast<std::size_t>(std::distance(imu.t_ns.begin(), after)) - 1;
  while (t < t_end_ns) {
    const int64_t next = k + 1 < imu.size() ? std::min(imu.t_ns[k + 1], t_end_ns) : t_end_ns;
    if (next > t) {
      integrate(next - t, imu.gyro[k].template cast<Scalar>(), imu.accel[k].template cast<Scalar>(),
                noise);
      t = next;
    }
    if (k + 1 < imu.size()) ++k;
  }
}

template <typename Scalar>
Mat3<Scalar> ImuPreintegration<Scalar>::correctedDeltaR(const Vec3T& b_g) const {
  return deltaR() * expSO3<Scalar>(d_R_d_bg_ * (b_g - bias_gyro_lin_));
}

template <typename Scalar>
Vec3<Scalar> ImuPreintegration<Scalar>::correctedDeltaV(const Vec3T& b_g, const Vec3T& b_a) const {
  return delta_v_ + d_v_d_bg_ * (b_g - bias_gyro_lin_) + d_v_d_ba_ * (b_a - bias_accel_lin_);
}

template <typename Scalar>
Vec3<Scalar> ImuPreintegration<Scalar>::correctedDeltaP(const Vec3T& b_g, const Vec3T& b_a) const {
  return delta_p_ + d_p_d_bg_ * (b_g - bias_gyro_lin_) + d_p_d_ba_ * (b_a - bias_accel_lin_);
}

template <typename Scalar>
ImuPreintegration<Scalar> preintegrate(const ImuData& imu, int64_t t_i_ns, int64_t t_j_ns,
                                       const Vec3<Scalar>& bias_gyro_lin,
                                       const Vec3<Scalar>& bias_accel_lin,
                                       const ImuSampleNoise<Scalar>& noise) {
  ImuPreintegration<Scalar> pre(t_i_ns, bias_gyro_lin, bias_accel_lin);
  pre.integrateUntil(imu, t_j_ns, noise);
  return pre;
}

#define MARGLAB_INST(S)                                                                           \
  template class ImuPreintegration<S>;                                                            \
  template ImuPreintegration<S> preintegrate<S>(const ImuData&, int64_t, int64_t, const Vec3<S>&, \
                                                const Vec3<S>&, const ImuSampleNoise<S>&);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
