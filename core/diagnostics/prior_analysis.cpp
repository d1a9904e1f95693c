#include "core/diagnostics/prior_analysis.h"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <limits>

#include "core/common/scalar.h"

namespace marglab {

PriorSpectrum analyzePrior(const MatXd& H_m) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  PriorSpectrum s;
  const Eigen::Index n = H_m.rows();
  s.eigenvalues = VecXd::Constant(n, kNaN);
  s.sigma_min = s.sigma_max = s.tolerance = kNaN;
  if (n == 0 || H_m.cols() != n || !H_m.allFinite()) return s;

  const MatXd H_sym = 0.5 * (H_m + H_m.transpose());
  const Eigen::SelfAdjointEigenSolver<MatXd> solver(H_sym, Eigen::EigenvaluesOnly);
  if (solver.info() != Eigen::Success) return s;

  s.eigenvalues = solver.eigenvalues();
  s.sigma_min = s.eigenvalues(0);
  s.sigma_max = s.eigenvalues(n - 1);
  s.tolerance = NumericTraits<double>::pinvRelativeTolerance(static_cast<int>(n)) *
                s.eigenvalues.cwiseAbs().maxCoeff();
  for (Eigen::Index i = 0; i < n; ++i) {
    const double lambda = s.eigenvalues(i);
    if (lambda < -s.tolerance) ++s.n_negative;
    if (std::abs(lambda) > s.tolerance) ++s.rank;
  }
  s.valid = true;
  return s;
}

MatXd hessianFromSqrt(const MatXd& J_m) {
  MatXd H = MatXd::Zero(J_m.cols(), J_m.cols());
  H.selfadjointView<Eigen::Lower>().rankUpdate(J_m.transpose());
  return H.selfadjointView<Eigen::Lower>();
}

VecXd gradientFromSqrt(const MatXd& J_m, const VecXd& r_m) { return J_m.transpose() * r_m; }

}  // namespace marglab
