#include "core/ba/pcg.h"

#include <fmt/core.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <vector>

#include "core/common/scalar.h"

namespace marglab {
namespace {

// The extreme eigenvalues of the Lanczos tridiagonal built from the CG coefficients.
void ritzValues(const std::vector<double>& alpha, const std::vector<double>& beta,
                CgSummary* summary) {
  const int k = static_cast<int>(alpha.size());
  if (k == 0) {
    summary->ritz_min = summary->ritz_max = std::numeric_limits<double>::quiet_NaN();
    return;
  }
  Eigen::VectorXd diagonal(k);
  Eigen::VectorXd off(std::max(k - 1, 0));
  for (int j = 0; j < k; ++j) {
    diagonal[j] = 1.0 / alpha[j] + (j > 0 ? beta[j - 1] / alpha[j - 1] : 0.0);
    if (j + 1 < k) off[j] = std::sqrt(beta[j]) / alpha[j];
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig;
  eig.computeFromTridiagonal(diagonal, off, Eigen::EigenvaluesOnly);
  summary->ritz_min = eig.eigenvalues().minCoeff();
  summary->ritz_max = eig.eigenvalues().maxCoeff();
}

}  // namespace

template <typename Scalar>
Status preconditionedCg(const CgOperators<Scalar>& ops, const VecX<Scalar>& b,
                        const CgOptions& options, VecX<Scalar>* x, CgSummary* summary) {
  const Eigen::Index n = b.size();
  x->setZero(n);
  VecX<Scalar> r = b, z(n), Ap(n);
  ops.apply_M_inverse(r, &z);
  VecX<Scalar> p = z;
  Scalar rho = r.dot(z);
  const Scalar r_stop = NumericTraits<Scalar>::kEpsilon * b.norm();
  double Q_previous = 0;
  std::vector<double> alphas, betas;
  Status status;
  summary->message = "maximum iterations";
  for (int k = 0; k < options.max_iterations; ++k) {
    if (r.norm() <= r_stop) {
      summary->message = "residual at working precision";
      break;
    }
    ops.apply_A(p, &Ap);
    const Scalar curvature = p.dot(Ap);
    if (!(curvature > Scalar(0)) || !std::isfinite(double(curvature))) {
      status = Status::Error(Status::Code::kSolveFailed,
                             fmt::format("CG: pᵀAp = {:.3e} at iteration {} (the reduced system is "
                                         "not positive definite in {})",
                                         double(curvature), k, NumericTraits<Scalar>::name()));
      break;
    }
    const Scalar alpha = rho / curvature;
    const VecX<Scalar> x_next = *x + alpha * p;
    // Q(x) = ½ xᵀAx − bᵀx = −½ (bᵀx + rᵀx) with r = b − Ax.
    r -= alpha * Ap;
    const double Q = -0.5 * double(b.dot(x_next) + r.dot(x_next));
    if (!std::isfinite(Q)) {
      status =
          Status::Error(Status::Code::kNotFinite, fmt::format("CG: non-finite iterate at {}", k));
      break;
    }
    if (k > 0 && Q > Q_previous) {
      summary->message = fmt::format("Q increased at iteration {} (stopped)", k);
      break;
    }
    *x = x_next;
    alphas.push_back(double(alpha));
    summary->iterations = k + 1;
    if (k > 0 && (k + 1) * (Q - Q_previous) / Q < options.eta) {
      summary->message = "forcing sequence";
      break;
    }
    Q_previous = Q;
    ops.apply_M_inverse(r, &z);
    const Scalar rho_next = r.dot(z);
    const Scalar beta = rho_next / rho;
    betas.push_back(double(beta));
    p = z + beta * p;
    rho = rho_next;
  }
  ritzValues(alphas, betas, summary);
  return status;
}

#define MARGLAB_INST(S)                                                                        \
  template Status preconditionedCg<S>(const CgOperators<S>&, const VecX<S>&, const CgOptions&, \
                                      VecX<S>*, CgSummary*);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
