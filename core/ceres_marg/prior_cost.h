#pragma once
// The marginalization prior as a Ceres cost function over the Markov blanket x_b = (x_1 … x_K)
// (Levine 2023, eq. 56; eq. 37 for the Schur route):
//
//   r(x_b) = r̃ + R̃ · δ,   δ = (Minus(x_1, x̌_1), …, Minus(x_K, x̌_K)) ∈ R^{Σ n_k},
//
// with R̃ (rows × Σ n_k) and r̃ the square-root prior and x̌_b the linearization point. The Jacobian
// with respect to the ambient block x_k is
//
//   ∂r/∂x_k = R̃_{:,k} · ∂Minus(y, x̌_k)/∂y |_{y = x_k}    (rows × ambient size of x_k),
//
// exact at every x_k (manifold_minus.h); Ceres then multiplies it by PlusJacobian(x_k). Using
// MinusJacobian(x̌_k) instead would only be right at x_k = x̌_k.

#include <ceres/cost_function.h>

#include <memory>
#include <vector>

#include "core/ceres_marg/manifold_minus.h"
#include "core/common/eigen_types.h"

namespace marglab::ceres_marg {

class MarginalizationPriorCost final : public ceres::CostFunction {
 public:
  // differences[k] describes block k (ambient size = parameter block size); x_lin[k] its
  // linearization point; R_tilde has Σ tangent sizes columns.
  MarginalizationPriorCost(std::vector<std::unique_ptr<BlockDifference>> differences,
                           std::vector<std::vector<double>> x_lin, MatXd R_tilde, VecXd r_tilde);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  const MatXd& sqrtInformation() const { return R_tilde_; }  // R̃
  const VecXd& residualOffset() const { return r_tilde_; }   // r̃
  const std::vector<std::vector<double>>& linearizationPoint() const { return x_lin_; }

 private:
  std::vector<std::unique_ptr<BlockDifference>> differences_;
  std::vector<std::vector<double>> x_lin_;
  std::vector<int> tangent_offsets_;
  int tangent_size_ = 0;
  MatXd R_tilde_;
  VecXd r_tilde_;
};

}  // namespace marglab::ceres_marg
