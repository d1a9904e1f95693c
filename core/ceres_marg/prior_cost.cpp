#include "core/ceres_marg/prior_cost.h"

#include <utility>

namespace marglab::ceres_marg {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

MarginalizationPriorCost::MarginalizationPriorCost(
    std::vector<std::unique_ptr<BlockDifference>> differences,
    std::vector<std::vector<double>> x_lin, MatXd R_tilde, VecXd r_tilde)
    : differences_(std::move(differences)),
      x_lin_(std::move(x_lin)),
      R_tilde_(std::move(R_tilde)),
      r_tilde_(std::move(r_tilde)) {
  set_num_residuals(static_cast<int>(r_tilde_.size()));
  for (const auto& difference : differences_) {
    mutable_parameter_block_sizes()->push_back(difference->ambientSize());
    tangent_offsets_.push_back(tangent_size_);
    tangent_size_ += difference->tangentSize();
  }
}

bool MarginalizationPriorCost::Evaluate(double const* const* parameters, double* residuals,
                                        double** jacobians) const {
  const int rows = num_residuals();
  VecXd delta(tangent_size_);
  Eigen::Map<VecXd> r(residuals, rows);
  r = r_tilde_;
  RowMatrix D_y;
  for (std::size_t k = 0; k < differences_.size(); ++k) {
    const BlockDifference& difference = *differences_[k];
    const int n_amb = difference.ambientSize();
    const int n_tan = difference.tangentSize();
    const bool want_jacobian = jacobians != nullptr && jacobians[k] != nullptr;
    if (want_jacobian) D_y.resize(n_tan, n_amb);
    if (!difference.evaluate(parameters[k], x_lin_[k].data(), delta.data() + tangent_offsets_[k],
                             want_jacobian ? D_y.data() : nullptr)) {
      return false;
    }
    const auto R_k = R_tilde_.middleCols(tangent_offsets_[k], n_tan);
    r.noalias() += R_k * delta.segment(tangent_offsets_[k], n_tan);
    if (want_jacobian) Eigen::Map<RowMatrix>(jacobians[k], rows, n_amb).noalias() = R_k * D_y;
  }
  return true;
}

}  // namespace marglab::ceres_marg
