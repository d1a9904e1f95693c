#pragma once
// IMU residuals between two VIO states i and j (docs/design.md §3), their Jacobians w.r.t. the ⊞
// increments of imu_state.h, and state prediction.
//
// Preintegration residual (9 rows, order [r_p; r_R; r_v] as the preintegration error of
// preintegration.h), Δt = t_j − t_i of the preintegration, g = g_w, biases b = (b_g,i, b_a,i):
//   r_p = R_iᵀ (p_j − p_i − v_i Δt − ½ g Δt²) − Δp(b)
//   r_R = log( ΔR(b_g)ᵀ R_iᵀ R_j )
//   r_v = R_iᵀ (v_j − v_i − g Δt) − Δv(b)
// with the first-order bias-corrected deltas; Δ(b) = Δ̄ + J (b − b̄), ΔR(b_g) = ΔR̄ Exp(J_R^g δb_g).
// The residual is −η of the preintegration error (r_R = log(Exp(−δφ))), so its covariance is Σ.
//
// Jacobians, columns [δ_i (15) | δ_j (15)], each δ = [δt; δφ; δv; δb_g; δb_a] with the LEFT
// rotation perturbation R ← Exp(δφ) R. With w_p, w_v the bracketed world vectors above:
//   ∂r_p/∂δt_i = −R_iᵀ            ∂r_p/∂δφ_i = R_iᵀ w_p^        ∂r_p/∂v_i = −R_iᵀ Δt
//   ∂r_p/∂b_g,i = −J_p^g          ∂r_p/∂b_a,i = −J_p^a          ∂r_p/∂δt_j = R_iᵀ
//   ∂r_v/∂δφ_i = R_iᵀ w_v^        ∂r_v/∂v_i = −R_iᵀ             ∂r_v/∂v_j = R_iᵀ
//   ∂r_v/∂b_g,i = −J_v^g          ∂r_v/∂b_a,i = −J_v^a
//   ∂r_R/∂δφ_i = −Jr⁻¹(r_R) R_jᵀ  ∂r_R/∂δφ_j = Jr⁻¹(r_R) R_jᵀ
//   ∂r_R/∂b_g,i = −Jl⁻¹(r_R) Jr(J_R^g δb_g) J_R^g
// Derivation: R_iᵀ → R_iᵀ Exp(−δφ_i) ≈ R_iᵀ (I − δφ_i^), so R_iᵀ w changes by R_iᵀ w^ δφ_i; with
// E = ΔR(b)ᵀ R_iᵀ R_j, a left δφ_j gives E Exp(R_jᵀ δφ_j) and a left δφ_i gives E Exp(−R_jᵀ δφ_i),
// and log(E Exp(x)) ≈ r_R + Jr⁻¹(r_R) x; the bias gives Exp(−Jr(J δb) J ε) E on the left, and
// Jr⁻¹(r) Exp(r)ᵀ = Jl⁻¹(r). All other blocks (including b_g,j, b_a,j) are zero.
//
// Weighting: Σ = L Lᵀ (Cholesky, computed in double), W = L⁻¹ (lower triangular, Wᵀ W = Σ⁻¹);
// the whitened residual is W r with Jacobian W J.
//
// Bias random walk (6 rows [r_g; r_a]):
//   r_g = (b_g,j − b_g,i) / (σ_rw,g √Δt),  r_a = (b_a,j − b_a,i) / (σ_rw,a √Δt),
// with the continuous random-walk densities of ImuNoise; Jacobian ∓ the weight on b_·,i / b_·,j.
//
// Prediction (Forster eq. 44, biases of state i, kept in the prediction):
//   R_j = R_i ΔR(b_g),  v_j = v_i + g Δt + R_i Δv(b),  p_j = p_i + v_i Δt + ½ g Δt² + R_i Δp(b).

#include <Eigen/Core>

#include "core/common/eigen_types.h"
#include "core/data/types.h"
#include "core/imu/imu_state.h"
#include "core/imu/preintegration.h"

namespace marglab {

template <typename Scalar>
class ImuFactor {
 public:
  using Vec3T = Vec3<Scalar>;
  using Vec9T = Vec<Scalar, 9>;
  using Mat9T = Mat<Scalar, 9, 9>;
  using Jacobian = Mat<Scalar, 9, 30>;  // columns [δ_i (15) | δ_j (15)]

  // Throws InputError when the preintegrated covariance is not positive definite (zero duration
  // or zero noise).
  ImuFactor(const ImuPreintegration<Scalar>& preintegration, const Vec3T& g_w);

  // Unweighted residual [r_p; r_R; r_v] and optionally its Jacobian.
  Vec9T residual(const ImuState<Scalar>& s_i, const ImuState<Scalar>& s_j,
                 Jacobian* J = nullptr) const;
  // W r and W J.
  Vec9T whitenedResidual(const ImuState<Scalar>& s_i, const ImuState<Scalar>& s_j,
                         Jacobian* J = nullptr) const;

  // W = L⁻¹ with Σ = L Lᵀ.
  const Mat9T& sqrtInformation() const { return sqrt_info_; }
  const ImuPreintegration<Scalar>& preintegration() const { return pre_; }
  const Vec3T& gravity() const { return g_w_; }

 private:
  ImuPreintegration<Scalar> pre_;
  Vec3T g_w_;
  Mat9T sqrt_info_;
};

// Weighted bias random walk residual [r_g; r_a] over dt_s seconds, Jacobian columns as ImuFactor.
template <typename Scalar>
Vec<Scalar, 6> biasRandomWalkResidual(const ImuState<Scalar>& s_i, const ImuState<Scalar>& s_j,
                                      Scalar dt_s, const ImuNoise& noise,
                                      Mat<Scalar, 6, 30>* J = nullptr);

// State at preintegration.endTimeNs() predicted from s_i (its biases kept).
template <typename Scalar>
ImuState<Scalar> predictState(const ImuState<Scalar>& s_i,
                              const ImuPreintegration<Scalar>& preintegration,
                              const Vec3<Scalar>& g_w);

}  // namespace marglab
