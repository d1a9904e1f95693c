#pragma once
// On-manifold IMU preintegration between two frames i and j (Forster et al., "On-Manifold
// Preintegration for Real-Time Visual-Inertial Odometry", T-RO 2017, §V–VI and appendix; the
// design of Basalt's IntegratedImuMeasurement: piecewise-constant samples, [p, R, v] order).
//
// Measurements. Gyro ω̃ and specific force ã in the body frame, at sample times t_k. With the
// bias linearization point (b̄_g, b̄_a): ω_k = ω̃_k − b̄_g, f_k = ã_k − b̄_a.
//
// Integration scheme: zero-order hold. Sample k holds on [t_k, t_{k+1}) (the last sample holds
// until t_j; when t_i precedes the first sample, the first sample holds back to t_i). The interval
// [t_i, t_j) is cut at the sample times and at t_i, t_j, so the partial first and last pieces are
// integrated with the sample in force there. Piece k of duration δt:
//   ΔR_{k+1} = ΔR_k Exp(ω_k δt)
//   Δv_{k+1} = Δv_k + ΔR_k f_k δt
//   Δp_{k+1} = Δp_k + Δv_k δt + ½ ΔR_k f_k δt²
// starting from (I, 0, 0). Exact when ω_b is constant within each piece and the world-frame
// specific force R_w_b f = a_w − g_w is constant (e.g. constant body rate and constant world
// acceleration with frames at sample times); otherwise first-order accurate in the sample period.
// Splitting at an interior time and composing the two halves reproduces the whole deltas exactly
// (and the covariance when the split is at a sample time, see below).
//
// Relation to the states (Forster eq. 33), Δt = t_j − t_i, g = g_w:
//   ΔR = R_iᵀ R_j,  Δv = R_iᵀ (v_j − v_i − g Δt),  Δp = R_iᵀ (p_j − p_i − v_i Δt − ½ g Δt²).
//
// Noise and covariance (Forster eq. 59–63). The measured increments carry the errors
//   ΔR̃ = ΔR Exp(δφ),  Δṽ = Δv + δv,  Δp̃ = Δp + δp,   η = [δp; δφ; δv]  (order p, R, v)
// and with white sample noise n_g, n_a (per axis variance σ_d² = σ²/Δt_s, Kalibr convention, Δt_s
// the IMU sample period, σ the continuous noise density of ImuNoise) one piece propagates
//   η_{k+1} = A η_k + B_g n_g + B_a n_a,
//   A = [ I  −½ ΔR_k f_k^ δt²   I δt ]   B_g = [ 0            ]   B_a = [ ½ ΔR_k δt² ]
//       [ 0   Exp(ω_k δt)ᵀ       0    ]         [ Jr(ω_k δt) δt ]         [ 0          ]
//       [ 0  −ΔR_k f_k^ δt       I    ]         [ 0            ]         [ ΔR_k δt    ]
//   Σ_{k+1} = A Σ_k Aᵀ + σ_g,d² B_g B_gᵀ + σ_a,d² B_a B_aᵀ,   Σ_0 = 0.
// (ΔR_k ΔR_kᵀ = I makes the accel term independent of ΔR_k.) Each piece draws its sample's noise
// n_k with the full sample variance σ²/Δt_s, scaled through B by the piece's δt. This is exact for
// a piece that is a whole sample interval or the partial first/last piece of this interval; a
// sample split between two preintegrations (or two integrateUntil calls) is treated as two
// independent draws, i.e. the correlation of neighbouring factors is ignored, as usual.
//
// Bias Jacobians for the first-order correction (Forster eq. 44, appendix B):
//   ΔR(b_g) ≈ ΔR̄ Exp(J_R^g δb_g),  Δv(b) ≈ Δv̄ + J_v^g δb_g + J_v^a δb_a,
//   Δp(b) ≈ Δp̄ + J_p^g δb_g + J_p^a δb_a,   δb = b − b̄,
// propagated per piece (old values on the right):
//   J_p^g += J_v^g δt − ½ ΔR_k f_k^ J_R^g δt²      J_p^a += J_v^a δt − ½ ΔR_k δt²
//   J_v^g −= ΔR_k f_k^ J_R^g δt                     J_v^a −= ΔR_k δt
//   J_R^g  = Exp(ω_k δt)ᵀ J_R^g − Jr(ω_k δt) δt.
//
// Times are int64 ns; the total duration is exact. ΔR is kept as a unit quaternion, renormalized
// per piece, so that float stays on the manifold.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>

#include "core/common/eigen_types.h"
#include "core/data/types.h"

namespace marglab {

// Offsets of the blocks of the 9-dim preintegration error / residual (Basalt's order).
struct PreintIndex {
  static constexpr int kPos = 0;
  static constexpr int kRot = 3;
  static constexpr int kVel = 6;
  static constexpr int kDim = 9;
};

// Discrete per-sample white-noise variances (per axis): σ_d² = σ² / Δt_s.
template <typename Scalar>
struct ImuSampleNoise {
  Scalar gyro_var = 0;   // [(rad/s)²]
  Scalar accel_var = 0;  // [(m/s²)²]

  // From the continuous densities of ImuNoise and the IMU sample period (EuRoC: 1/200 s).
  static ImuSampleNoise fromDensities(const ImuNoise& noise, double sample_period_s) {
    ImuSampleNoise n;
    n.gyro_var =
        static_cast<Scalar>(noise.gyro_noise_density * noise.gyro_noise_density / sample_period_s);
    n.accel_var = static_cast<Scalar>(noise.accel_noise_density * noise.accel_noise_density /
                                      sample_period_s);
    return n;
  }
};

template <typename Scalar>
class ImuPreintegration {
 public:
  using Vec3T = Vec3<Scalar>;
  using Mat3T = Mat3<Scalar>;
  using Mat9T = Mat<Scalar, 9, 9>;

  // Empty preintegration at t_start_ns (identity deltas, zero covariance and Jacobians) with the
  // bias linearization point (b̄_g, b̄_a).
  ImuPreintegration(int64_t t_start_ns, const Vec3T& bias_gyro_lin, const Vec3T& bias_accel_lin);

  // One zero-order-hold piece of duration dt_ns > 0 with the raw (bias-including) sample.
  void integrate(int64_t dt_ns, const Vec3T& gyro, const Vec3T& accel,
                 const ImuSampleNoise<Scalar>& noise);

  // Continues from endTimeNs() to t_end_ns through the samples of imu (see the header comment
  // for which sample holds where). Throws InputError when imu is empty or t_end_ns < endTimeNs().
  void integrateUntil(const ImuData& imu, int64_t t_end_ns, const ImuSampleNoise<Scalar>& noise);

  int64_t startTimeNs() const { return t_start_ns_; }
  int64_t endTimeNs() const { return t_start_ns_ + dt_ns_; }
  int64_t durationNs() const { return dt_ns_; }
  Scalar durationSeconds() const { return static_cast<Scalar>(static_cast<double>(dt_ns_) * 1e-9); }

  const Vec3T& biasGyroLin() const { return bias_gyro_lin_; }
  const Vec3T& biasAccelLin() const { return bias_accel_lin_; }

  // Deltas at the bias linearization point.
  const Eigen::Quaternion<Scalar>& deltaQ() const { return delta_q_; }
  Mat3T deltaR() const { return delta_q_.toRotationMatrix(); }
  const Vec3T& deltaV() const { return delta_v_; }
  const Vec3T& deltaP() const { return delta_p_; }

  // Bias Jacobians J_R^g, J_v^g, J_v^a, J_p^g, J_p^a (header comment).
  const Mat3T& d_R_d_bg() const { return d_R_d_bg_; }
  const Mat3T& d_v_d_bg() const { return d_v_d_bg_; }
  const Mat3T& d_v_d_ba() const { return d_v_d_ba_; }
  const Mat3T& d_p_d_bg() const { return d_p_d_bg_; }
  const Mat3T& d_p_d_ba() const { return d_p_d_ba_; }

  // First-order bias-corrected deltas at biases (b_g, b_a).
  Mat3T correctedDeltaR(const Vec3T& b_g) const;
  Vec3T correctedDeltaV(const Vec3T& b_g, const Vec3T& b_a) const;
  Vec3T correctedDeltaP(const Vec3T& b_g, const Vec3T& b_a) const;

  // Σ of [δp; δφ; δv].
  const Mat9T& covariance() const { return cov_; }

  template <typename T>
  ImuPreintegration<T> cast() const {
    ImuPreintegration<T> out(t_start_ns_, bias_gyro_lin_.template cast<T>(),
                             bias_accel_lin_.template cast<T>());
    out.dt_ns_ = dt_ns_;
    out.delta_q_ = delta_q_.template cast<T>();
    out.delta_v_ = delta_v_.template cast<T>();
    out.delta_p_ = delta_p_.template cast<T>();
    out.d_R_d_bg_ = d_R_d_bg_.template cast<T>();
    out.d_v_d_bg_ = d_v_d_bg_.template cast<T>();
    out.d_v_d_ba_ = d_v_d_ba_.template cast<T>();
    out.d_p_d_bg_ = d_p_d_bg_.template cast<T>();
    out.d_p_d_ba_ = d_p_d_ba_.template cast<T>();
    out.cov_ = cov_.template cast<T>();
    return out;
  }

 private:
  template <typename>
  friend class ImuPreintegration;

  int64_t t_start_ns_;
  int64_t dt_ns_ = 0;
  Vec3T bias_gyro_lin_;
  Vec3T bias_accel_lin_;
  Eigen::Quaternion<Scalar> delta_q_ = Eigen::Quaternion<Scalar>::Identity();
  Vec3T delta_v_ = Vec3T::Zero();
  Vec3T delta_p_ = Vec3T::Zero();
  Mat3T d_R_d_bg_ = Mat3T::Zero();
  Mat3T d_v_d_bg_ = Mat3T::Zero();
  Mat3T d_v_d_ba_ = Mat3T::Zero();
  Mat3T d_p_d_bg_ = Mat3T::Zero();
  Mat3T d_p_d_ba_ = Mat3T::Zero();
  Mat9T cov_ = Mat9T::Zero();
};

// Preintegration of imu over [t_i_ns, t_j_ns] with bias linearization point (b̄_g, b̄_a).
// Throws InputError when imu is empty or t_j_ns < t_i_ns.
template <typename Scalar>
ImuPreintegration<Scalar> preintegrate(const ImuData& imu, int64_t t_i_ns, int64_t t_j_ns,
                                       const Vec3<Scalar>& bias_gyro_lin,
                                       const Vec3<Scalar>& bias_accel_lin,
                                       const ImuSampleNoise<Scalar>& noise);

}  // namespace marglab
