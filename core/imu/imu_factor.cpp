#include "core/imu/imu_factor.h"

#include <fmt/core.h>

#include <Eigen/Cholesky>
#include <cmath>

#include "core/common/error.h"
#include "core/common/scalar.h"
#include "core/geometry/so3.h"

namespace marglab {

template <typename Scalar>
ImuFactor<Scalar>::ImuFactor(const ImuPreintegration<Scalar>& preintegration, const Vec3T& g_w)
    : pre_(preintegration), g_w_(g_w) {
  // In double even for float: over a 0.05 s frame with EuRoC noise the diagonal of Σ spans
  // ~1e-10 (δp) to ~1e-7 (δv) and δp, δv are strongly correlated; W is rounded to Scalar once.
  const Eigen::Matrix<double, 9, 9> cov = pre_.covariance().template cast<double>();
  const Eigen::LLT<Eigen::Matrix<double, 9, 9>> llt(cov);
  if (llt.info() != Eigen::Success || !cov.allFinite()) {
    throw InputError(
        "", 0,
        fmt::format("IMU factor between the frames at t = {} ns and t = {} ns ({:.6g} s): the "
                    "preintegrated covariance is not positive definite (a zero duration, zero "
                    "noise, or IMU samples far outside the sensor's range?)",
                    pre_.startTimeNs(), pre_.endTimeNs(),
                    static_cast<double>(pre_.durationSeconds())));
  }
  const Eigen::Matrix<double, 9, 9> W =
      llt.matrixL().solve(Eigen::Matrix<double, 9, 9>::Identity());
  sqrt_info_ = W.template cast<Scalar>().template triangularView<Eigen::Lower>();
}

template <typename Scalar>
typename ImuFactor<Scalar>::Vec9T ImuFactor<Scalar>::residual(const ImuState<Scalar>& s_i,
                                                              const ImuState<Scalar>& s_j,
                                                              Jacobian* J) const {
  using Mat3T = Mat3<Scalar>;
  constexpr int P = PreintIndex::kPos, O = PreintIndex::kRot, V = PreintIndex::kVel;
  const Scalar dt = pre_.durationSeconds();
  const Mat3T R_i = s_i.T_w_i.rotationMatrix();
  const Mat3T Rt_i = R_i.transpose();
  const Vec3T dbg = s_i.b_g - pre_.biasGyroLin();
  const Vec3T phi_bg = pre_.d_R_d_bg() * dbg;

  const Vec3T w_p = s_j.T_w_i.translation() - s_i.T_w_i.translation() - dt * s_i.v_w -
                    Scalar(0.5) * dt * dt * g_w_;
  const Vec3T w_v = s_j.v_w - s_i.v_w - dt * g_w_;

  Vec9T r;
  r.template segment<3>(P) = Rt_i * w_p - pre_.correctedDeltaP(s_i.b_g, s_i.b_a);
  r.template segment<3>(V) = Rt_i * w_v - pre_.correctedDeltaV(s_i.b_g, s_i.b_a);
  // E = ΔR(b)ᵀ R_iᵀ R_j through quaternions (renormalized products stay on the manifold).
  const Eigen::Quaternion<Scalar> q_corr = pre_.deltaQ() * expSO3Quaternion(phi_bg);
  const Eigen::Quaternion<Scalar> q_E =
      q_corr.conjugate() * s_i.T_w_i.unitQuaternion().conjugate() * s_j.T_w_i.unitQuaternion();
  const Vec3T r_R = logSO3(q_E.normalized());
  r.template segment<3>(O) = r_R;

  if (J) {
    constexpr int kJ = ImuStateIndex::kDim;
    constexpr int SP = ImuStateIndex::kPos, SR = ImuStateIndex::kRot, SV = ImuStateIndex::kVel,
                  SG = ImuStateIndex::kBiasGyro, SA = ImuStateIndex::kBiasAccel;
    J->setZero();
    J->template block<3, 3>(P, SP) = -Rt_i;
    J->template block<3, 3>(P, SR) = Rt_i * hat(w_p);
    J->template block<3, 3>(P, SV) = -dt * Rt_i;
    J->template block<3, 3>(P, SG) = -pre_.d_p_d_bg();
    J->template block<3, 3>(P, SA) = -pre_.d_p_d_ba();
    J->template block<3, 3>(P, kJ + SP) = Rt_i;

    const Mat3T M = rightJacobianInvSO3(r_R) * s_j.T_w_i.rotationMatrix().transpose();
    J->template block<3, 3>(O, SR) = -M;
    J->template block<3, 3>(O, SG) =
        -leftJacobianInvSO3(r_R) * rightJacobianSO3(phi_bg) * pre_.d_R_d_bg();
    J->template block<3, 3>(O, kJ + SR) = M;

    J->template block<3, 3>(V, SR) = Rt_i * hat(w_v);
    J->template block<3, 3>(V, SV) = -Rt_i;
    J->template block<3, 3>(V, SG) = -pre_.d_v_d_bg();
    J->template block<3, 3>(V, SA) = -pre_.d_v_d_ba();
    J->template block<3, 3>(V, kJ + SV) = Rt_i;
  }
  return r;
}

template <typename Scalar>
typename ImuFactor<Scalar>::Vec9T ImuFactor<Scalar>::whitenedResidual(const ImuState<Scalar>& s_i,
                                                                      const ImuState<Scalar>& s_j,
                                                                      Jacobian* J) const {
  const Vec9T r = residual(s_i, s_j, J);
  if (J) *J = (sqrt_info_.template triangularView<Eigen::Lower>() * (*J)).eval();
  return sqrt_info_.template triangularView<Eigen::Lower>() * r;
}

template <typename Scalar>
Vec<Scalar, 6> biasRandomWalkResidual(const ImuState<Scalar>& s_i, const ImuState<Scalar>& s_j,
                                      Scalar dt_s, const ImuNoise& noise, Mat<Scalar, 6, 30>* J) {
  const double sqrt_dt = std::sqrt(static_cast<double>(dt_s));
  const auto w_g = static_cast<Scalar>(1.0 / (noise.gyro_random_walk * sqrt_dt));
  const auto w_a = static_cast<Scalar>(1.0 / (noise.accel_random_walk * sqrt_dt));
  Vec<Scalar, 6> r;
  r.template head<3>() = w_g * (s_j.b_g - s_i.b_g);
  r.template tail<3>() = w_a * (s_j.b_a - s_i.b_a);
  if (J) {
    constexpr int kJ = ImuStateIndex::kDim;
    constexpr int SG = ImuStateIndex::kBiasGyro, SA = ImuStateIndex::kBiasAccel;
    const Mat3<Scalar> I = Mat3<Scalar>::Identity();
    J->setZero();
    J->template block<3, 3>(0, SG) = -w_g * I;
    J->template block<3, 3>(0, kJ + SG) = w_g * I;
    J->template block<3, 3>(3, SA) = -w_a * I;
    J->template block<3, 3>(3, kJ + SA) = w_a * I;
  }
  return r;
}

template <typename Scalar>
ImuState<Scalar> predictState(const ImuState<Scalar>& s_i,
                              const ImuPreintegration<Scalar>& preintegration,
                              const Vec3<Scalar>& g_w) {
  const Scalar dt = preintegration.durationSeconds();
  const Vec3<Scalar> dbg = s_i.b_g - preintegration.biasGyroLin();
  const Eigen::Quaternion<Scalar>& q_i = s_i.T_w_i.unitQuaternion();
  ImuState<Scalar> s_j = s_i;
  s_j.t_ns = preintegration.endTimeNs();
  s_j.T_w_i = SE3<Scalar>(
      q_i * preintegration.deltaQ() * expSO3Quaternion<Scalar>(preintegration.d_R_d_bg() * dbg),
      s_i.T_w_i.translation() + dt * s_i.v_w + Scalar(0.5) * dt * dt * g_w +
          q_i * preintegration.correctedDeltaP(s_i.b_g, s_i.b_a));
  s_j.v_w = s_i.v_w + dt * g_w + q_i * preintegration.correctedDeltaV(s_i.b_g, s_i.b_a);
  return s_j;
}

#define MARGLAB_INST(S)                                                                   \
  template class ImuFactor<S>;                                                            \
  template Vec<S, 6> biasRandomWalkResidual<S>(const ImuState<S>&, const ImuState<S>&, S, \
                                               const ImuNoise&, Mat<S, 6, 30>*);          \
  template ImuState<S> predictState<S>(const ImuState<S>&, const ImuPreintegration<S>&,   \
                                       const Vec3<S>&);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
