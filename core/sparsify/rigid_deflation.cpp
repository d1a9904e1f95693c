#include "core/sparsify/rigid_deflation.h"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <string>

#include "core/common/scalar.h"

namespace marglab {

double RigidDeflation::logDetChange() const { return mu.array().log().sum(); }

RigidDeflation rigidDeflation(const Eigen::MatrixXd& B, const Eigen::MatrixXd& G_d) {
  RigidDeflation out;
  const Eigen::Index m = B.rows(), k = B.cols();
  out.A = Eigen::MatrixXd::Identity(m, m);
  out.Q.resize(m, 0);
  if (G_d.rows() != k || G_d.cols() != k) {
    out.status = Status::Error(Status::Code::kInvalidArgument,
                               "rigid deflation: G_d is not k × k for B's k columns");
    return out;
  }
  if (!B.allFinite() || !G_d.allFinite()) {
    out.status = Status::Error(Status::Code::kNotFinite,
                               "rigid deflation: non-finite rigid-direction information");
    return out;
  }
  if (m == 0 || k == 0) return out;
  // Whiten span E by G_s = BᵀB over its numerical range (header: W = V₊ S₊^(−1/2)).
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig_s(B.transpose() * B);
  const Eigen::VectorXd& s = eig_s.eigenvalues();
  const double s_max = s.maxCoeff();
  if (!(s_max > 0)) return out;  // the factors carry no rigid-motion information
  const double cut = NumericTraits<double>::pinvRelativeTolerance(static_cast<int>(k)) * s_max;
  Eigen::Index first = 0;  // eigenvalues ascend
  while (s(first) <= cut) ++first;
  const Eigen::MatrixXd W = eig_s.eigenvectors().rightCols(k - first) *
                            s.tail(k - first).cwiseSqrt().cwiseInverse().asDiagonal();
  const Eigen::MatrixXd G_d_sym = G_d.selfadjointView<Eigen::Lower>();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig_m(W.transpose() * G_d_sym * W);
  const Eigen::VectorXd& mu = eig_m.eigenvalues();
  // An excess within rounding of M (its μ_j carry errors of a few k ε) is not one: equal
  // information stays as unary factors. Ascending: the deflated directions come first.
  const double excess_min = 100 * NumericTraits<double>::pinvRelativeTolerance(static_cast<int>(k));
  Eigen::Index d = 0;
  while (d < mu.size() && mu(d) < 1 - excess_min) ++d;
  if (d == 0) return out;
  out.mu = mu.head(d).cwiseMax(0.0);
  out.Q = B * W * eig_m.eigenvectors().leftCols(d);
  const Eigen::VectorXd shrink = Eigen::VectorXd::Ones(d) - out.mu.cwiseSqrt();
  out.A.noalias() -= out.Q * shrink.asDiagonal() * out.Q.transpose();
  return out;
}

}  // namespace marglab
