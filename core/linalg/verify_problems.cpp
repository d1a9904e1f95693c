#include "core/linalg/verify_problems.h"

#include <Eigen/QR>
#include <Eigen/SVD>
#include <cmath>
#include <random>

namespace marglab {
namespace {

using MatXl = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;

// Box–Muller on mt19937_64 bits: the same numbers on every platform for a seed.
class Gaussian {
 public:
  explicit Gaussian(std::uint64_t seed) : engine_(seed) {}
  double operator()() {
    const double u1 = (static_cast<double>(engine_() >> 11) + 0.5) * 0x1.0p-53;
    const double u2 = static_cast<double>(engine_() >> 11) * 0x1.0p-53;
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  }
  MatXd matrix(int rows, int cols) {
    MatXd M(rows, cols);
    for (int j = 0; j < cols; ++j) {
      for (int i = 0; i < rows; ++i) M(i, j) = (*this)();
    }
    return M;
  }

 private:
  std::mt19937_64 engine_;
};

MatXd randomOrthonormalColumns(Gaussian& gauss, int rows, int cols) {
  const MatXd G = gauss.matrix(rows, cols);
  Eigen::HouseholderQR<MatXd> qr(G);
  return qr.householderQ() * MatXd::Identity(rows, cols);
}

}  // namespace

const char* toString(ProblemKind kind) {
  switch (kind) {
    case ProblemKind::kFullRank:
      return "full-rank";
    case ProblemKind::kRankDeficientMarg:
      return "rank-deficient J_mu";
    case ProblemKind::kCoupledRankDeficiency:
      return "coupled (eq. 26 violated)";
    case ProblemKind::kIllConditioned:
      return "ill-conditioned";
  }
  return "unknown";
}

TestProblem makeProblem(const ProblemSpec& spec) {
  Gaussian gauss(spec.seed);
  TestProblem problem;
  problem.spec = spec;
  const int n = spec.n_marg + spec.n_keep;
  // Scale 1/√rows keeps column norms O(1), the regime the absolute √ε threshold is made for.
  const double scale = 1.0 / std::sqrt(static_cast<double>(spec.n_rows));
  switch (spec.kind) {
    case ProblemKind::kFullRank:
      problem.J = scale * gauss.matrix(spec.n_rows, n);
      break;
    case ProblemKind::kRankDeficientMarg: {
      problem.J = scale * gauss.matrix(spec.n_rows, n);
      const int rank = spec.n_marg - spec.marg_rank_deficit;
      problem.J.leftCols(spec.n_marg) = scale * gauss.matrix(spec.n_rows, rank) *
                                        gauss.matrix(rank, spec.n_marg) /
                                        std::sqrt(static_cast<double>(rank));
      break;
    }
    case ProblemKind::kCoupledRankDeficiency: {
      problem.J = scale * gauss.matrix(spec.n_rows, n);
      // One kept column lies in the span of the marginalized ones: rank(J_μ) + rank(J_κ) > rank(J).
      const VecXd c = gauss.matrix(spec.n_marg, 1) / std::sqrt(static_cast<double>(spec.n_marg));
      problem.J.col(spec.n_marg) = problem.J.leftCols(spec.n_marg) * c;
      break;
    }
    case ProblemKind::kIllConditioned: {
      const MatXd U = randomOrthonormalColumns(gauss, spec.n_rows, n);
      const MatXd V = randomOrthonormalColumns(gauss, n, n);
      VecXd sigma(n);
      for (int i = 0; i < n; ++i) {
        sigma[i] = std::pow(spec.condition, -static_cast<double>(i) / (n - 1));
      }
      problem.J = U * sigma.asDiagonal() * V.transpose();
      break;
    }
  }
  problem.r = scale * gauss.matrix(spec.n_rows, 1);
  return problem;
}

std::vector<ProblemSpec> standardProblemSpecs() {
  std::vector<ProblemSpec> specs;
  std::uint64_t seed = 1000;
  specs.push_back({ProblemKind::kFullRank, 40, 6, 12, 0, 1.0, seed++});
  specs.push_back({ProblemKind::kFullRank, 90, 15, 45, 0, 1.0, seed++});
  specs.push_back({ProblemKind::kRankDeficientMarg, 40, 6, 12, 2, 1.0, seed++});
  specs.push_back({ProblemKind::kRankDeficientMarg, 90, 15, 45, 4, 1.0, seed++});
  specs.push_back({ProblemKind::kCoupledRankDeficiency, 40, 6, 12, 0, 1.0, seed++});
  specs.push_back({ProblemKind::kCoupledRankDeficiency, 90, 15, 45, 0, 1.0, seed++});
  for (double condition : {1e2, 1e4, 1e6, 1e8}) {
    specs.push_back({ProblemKind::kIllConditioned, 60, 9, 21, 0, condition, seed++});
  }
  return specs;
}

PseudoSchurReference pseudoSchurReference(const MatXd& J, const VecXd& r, int n_marg,
                                          double rel_rank_tol) {
  const int n = static_cast<int>(J.cols());
  const int n_keep = n - n_marg;
  const int N = static_cast<int>(J.rows());
  MatXl A(N, n + 1);
  A.leftCols(n) = J.cast<long double>();
  A.col(n) = r.cast<long double>();
  const MatXl J_marg = A.leftCols(n_marg);
  const MatXl A_keep = A.rightCols(n_keep + 1);

  PseudoSchurReference ref;
  Eigen::JacobiSVD<MatXl> svd_marg(J_marg, Eigen::ComputeThinU);
  const auto& s_marg = svd_marg.singularValues();
  const long double s_marg_max = s_marg.size() ? s_marg[0] : 0.0L;
  auto near_cutoff = [](long double s, long double cutoff) {
    return s > cutoff / 10 && s < cutoff * 10;
  };
  for (Eigen::Index i = 0; i < s_marg.size(); ++i) {
    const long double cutoff = rel_rank_tol * s_marg_max;
    if (s_marg[i] > cutoff) {
      ++ref.rank_marg;
      ref.sigma_min_marg = static_cast<double>(s_marg[i]);
    }
    ref.rank_marg_ambiguous = ref.rank_marg_ambiguous || near_cutoff(s_marg[i], cutoff);
  }
  const MatXl U1 = svd_marg.matrixU().leftCols(ref.rank_marg);
  const MatXl projected = A_keep - U1 * (U1.transpose() * A_keep);
  const MatXl S = A_keep.transpose() * projected;  // [J_κ r]ᵀ (I − U₁U₁ᵀ) [J_κ r]
  ref.H_tilde = S.topLeftCorner(n_keep, n_keep).cast<double>();
  ref.b_tilde = S.col(n_keep).head(n_keep).cast<double>();

  Eigen::JacobiSVD<MatXl> svd_all(A.leftCols(n));
  const auto& s_all = svd_all.singularValues();
  for (Eigen::Index i = 0; i < s_all.size(); ++i) {
    const long double cutoff = rel_rank_tol * s_all[0];
    if (s_all[i] > cutoff) ++ref.rank_total;
    ref.rank_total_ambiguous = ref.rank_total_ambiguous || near_cutoff(s_all[i], cutoff);
  }
  ref.norm_A = static_cast<double>(Eigen::JacobiSVD<MatXl>(A).singularValues()[0]);
  ref.norm_A_keep = static_cast<double>(Eigen::JacobiSVD<MatXl>(A_keep).singularValues()[0]);
  ref.norm_J_marg = static_cast<double>(s_marg_max);
  return ref;
}

ErrorTolerances errorTolerances(const PseudoSchurReference& ref, int n_cols, double epsilon) {
  constexpr double c = 10.0;
  const double base = c * n_cols * epsilon;
  const double sigma = ref.sigma_min_marg > 0 ? ref.sigma_min_marg : 1.0;
  const double qr_abs =
      base * ref.norm_A * (2.0 * ref.norm_A_keep + ref.norm_A_keep * ref.norm_A_keep / sigma);
  const double amplification = 1.0 + ref.norm_A_keep * ref.norm_J_marg / (sigma * sigma);
  const double sc_abs = base * ref.norm_A * ref.norm_A * amplification * amplification;
  const double norm_H = ref.H_tilde.norm();
  const double norm_b = ref.b_tilde.norm();
  return {qr_abs / norm_H, qr_abs / norm_b, sc_abs / norm_H, sc_abs / norm_b};
}

}  // namespace marglab
