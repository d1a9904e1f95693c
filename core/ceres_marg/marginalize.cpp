#include "core/ceres_marg/marginalize.h"

#include <ceres/crs_matrix.h>
#include <fmt/core.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <chrono>
#include <limits>
#include <memory>
#include <unordered_map>
#include <unordered_set>

#include "core/ceres_marg/sparse_cholesky.h"
#include "core/linalg/schur.h"

namespace marglab::ceres_marg {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

Status invalid(std::string message) {
  return Status::Error(Status::Code::kInvalidArgument, "marginalize: " + std::move(message));
}

// Writes the linearization points into the blanket blocks for the evaluation and puts the
// current values back when it goes out of scope.
class ValueSwap {
 public:
  ValueSwap(const std::map<const double*, std::vector<double>>& points,
            const std::vector<double*>& blanket) {
    for (double* block : blanket) {
      const auto it = points.find(block);
      if (it == points.end()) continue;
      saved_.push_back({block, std::vector<double>(block, block + it->second.size())});
      std::copy(it->second.begin(), it->second.end(), block);
    }
  }
  ~ValueSwap() {
    for (const auto& [block, values] : saved_) std::copy(values.begin(), values.end(), block);
  }
  ValueSwap(const ValueSwap&) = delete;
  ValueSwap& operator=(const ValueSwap&) = delete;

 private:
  std::vector<std::pair<double*, std::vector<double>>> saved_;
};

struct SqrtPriorResult {
  MatXd R;
  VecXd r;
  int marg_rank = 0;
  Status status;
  std::shared_ptr<const SparseNormalCholesky> factor;  // kSparseSchur: of Λ_mm
};

// Eigenvalue cut-off for the Hessian-based methods. Absolute: τ². Relative: t · s with
// t = max(τ², n·ε) and s = max_i ‖J_:,i‖² = max_i H_ii, the scale of the input Hessian. τ² is the
// QR threshold moved to the eigenvalue (squared singular value) scale; n·ε is the floor below which
// eigenvalues of a Hessian formed and Schur-complemented in double precision are rounding noise,
// so a gauge direction of x_b is recognized as such (as the QR recognizes it) instead of being
// kept as a direction of spurious information.
double eigenvalueCut(const MarginalizationOptions& opt, int n, double hessian_scale) {
  const double tau_sq = opt.threshold * opt.threshold;
  if (opt.threshold_mode == RankThresholdMode::kAbsolute) return tau_sq;
  return std::max(tau_sq, NumericTraits<double>::pinvRelativeTolerance(n)) * hessian_scale;
}

// Eq. 37: Λ_t = U D Uᵀ  →  R̃ = D^{1/2} Uᵀ, r̃ = D^{-1/2} Uᵀ g_t over eigenvalues λ > cut, in
// decreasing order.
void hessianToSqrtEig(const MatXd& Lambda_t, const VecXd& g_t, double cut, SqrtPriorResult* out) {
  const Eigen::SelfAdjointEigenSolver<MatXd> eig(Lambda_t);
  const VecXd& lambda = eig.eigenvalues();  // increasing
  int rank = 0;
  for (Eigen::Index i = 0; i < lambda.size(); ++i) rank += lambda[i] > cut ? 1 : 0;
  out->R.resize(rank, Lambda_t.cols());
  out->r.resize(rank);
  for (int row = 0; row < rank; ++row) {
    const Eigen::Index i = lambda.size() - 1 - row;
    const double s = std::sqrt(lambda[i]);
    out->R.row(row) = s * eig.eigenvectors().col(i).transpose();
    out->r[row] = eig.eigenvectors().col(i).dot(g_t) / s;
  }
}

SqrtPriorResult viaQr(const MatXd& J, const VecXd& f, int n_m, const MarginalizationOptions& opt) {
  SqrtPriorResult out;
  const Eigen::Index n = J.cols();
  MatXd A(J.rows(), n + 1);
  A.leftCols(n) = J;
  A.col(n) = f;
  FlatQrOptions<double> qr_options;
  qr_options.mode = opt.threshold_mode;
  qr_options.threshold = opt.threshold;
  FlatQrMarginalization<double> qr = flatQrMarginalize<double>(std::move(A), n_m, qr_options);
  out.status = qr.status;
  out.marg_rank = qr.marg_rank;
  const int rows = qr.total_rank - qr.marg_rank;
  out.R = qr.prior.J.topRows(rows);
  out.r = qr.prior.r.head(rows);
  return out;
}

SqrtPriorResult viaSchur(const MatXd& J, const VecXd& f, int n_m,
                         const MarginalizationOptions& opt) {
  SqrtPriorResult out;
  const MatXd H = J.transpose() * J;
  const VecXd b = J.transpose() * f;
  const double cut =
      eigenvalueCut(opt, static_cast<int>(H.rows()), H.rows() > 0 ? H.diagonal().maxCoeff() : 0.0);
  PinvOptions<double> pinv;
  pinv.mode = RankThresholdMode::kAbsolute;
  pinv.threshold = cut;
  const SchurMarginalization<double> sc = schurMarginalize<double>(H, b, n_m, pinv);
  out.status = sc.status;
  out.marg_rank = sc.marg_rank;
  if (!sc.status.ok()) return out;
  hessianToSqrtEig(sc.prior.H, sc.prior.b, cut, &out);
  return out;
}

// J_m and J_b as two compressed sparse matrices (columns < n_m and the rest of the CRS).
void splitColumns(const ceres::CRSMatrix& crs, int n_m, SparseRowMatrix* J_m,
                  SparseRowMatrix* J_b) {
  std::vector<Eigen::Triplet<double, int>> m, b;
  m.reserve(crs.values.size());
  for (int row = 0; row < crs.num_rows; ++row) {
    for (int k = crs.rows[row]; k < crs.rows[row + 1]; ++k) {
      const int col = crs.cols[k];
      if (col < n_m) {
        m.emplace_back(row, col, crs.values[k]);
      } else {
        b.emplace_back(row, col - n_m, crs.values[k]);
      }
    }
  }
  *J_m = SparseRowMatrix(crs.num_rows, n_m);
  J_m->setFromTriplets(m.begin(), m.end());
  J_m->makeCompressed();
  *J_b = SparseRowMatrix(crs.num_rows, crs.num_cols - n_m);
  J_b->setFromTriplets(b.begin(), b.end());
  J_b->makeCompressed();
}

// Λ_mm = Pᵀ L Lᵀ P by one sparse Cholesky; with [Y_b | y_g] = L⁻¹ P [Λ_mb | g_m] (the forward half
// of a solve) Λ_bm Λ_mm⁻¹ Λ_mb = Y_bᵀY_b and Λ_bm Λ_mm⁻¹ g_m = Y_bᵀ y_g. J_b stays sparse: only
// the rows of the residuals that touch the blanket are nonzero.
SqrtPriorResult viaSparseSchur(const ceres::CRSMatrix& crs, const VecXd& f, int n_m,
                               const MarginalizationOptions& opt) {
  SqrtPriorResult out;
  const int n_b = crs.num_cols - n_m;
  SparseRowMatrix J_m, J_b;
  splitColumns(crs, n_m, &J_m, &J_b);
  auto cholesky = std::make_shared<SparseNormalCholesky>();
  out.status = cholesky->factorize(J_m);
  if (!out.status.ok()) return out;
  out.factor = cholesky;
  out.marg_rank = n_m;
  MatXd rhs(n_m, n_b + 1);
  rhs.leftCols(n_b) = J_m.transpose() * J_b;  // Λ_mb
  rhs.col(n_b) = J_m.transpose() * f;         // g_m
  MatXd Y;
  out.status = cholesky->solveForward(rhs, &Y);
  if (!out.status.ok()) return out;
  const MatXd Lambda_bb = MatXd(J_b.transpose() * J_b);
  const MatXd Lambda_t = Lambda_bb - Y.leftCols(n_b).transpose() * Y.leftCols(n_b);
  const VecXd g_t = J_b.transpose() * f - Y.leftCols(n_b).transpose() * Y.col(n_b);
  double hessian_scale = n_b > 0 ? Lambda_bb.diagonal().maxCoeff() : 0.0;
  VecXd column_norms_sq = VecXd::Zero(n_m);
  for (int row = 0; row < J_m.outerSize(); ++row) {
    for (SparseRowMatrix::InnerIterator it(J_m, row); it; ++it) {
      column_norms_sq[it.col()] += it.value() * it.value();
    }
  }
  if (n_m > 0) hessian_scale = std::max(hessian_scale, column_norms_sq.maxCoeff());
  hessianToSqrtEig(Lambda_t, g_t, eigenvalueCut(opt, crs.num_cols, hessian_scale), &out);
  return out;
}

double conditionNumber(const MatXd& R) {
  if (R.rows() == 0) return 0.0;
  const Eigen::JacobiSVD<MatXd> svd(R);
  const VecXd& s = svd.singularValues();
  double s_min = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < s.size(); ++i) {
    if (s[i] > 0) s_min = std::min(s_min, s[i]);
  }
  return s.size() > 0 && s[0] > 0 ? s[0] / s_min : 0.0;
}

}  // namespace

const char* toString(Method method) {
  switch (method) {
    case Method::kQr:
      return "qr";
    case Method::kSchur:
      return "schur";
    case Method::kSparseSchur:
      return "sparse-schur";
  }
  return "?";
}

bool parseMethod(const std::string& text, Method* method) {
  for (Method m : {Method::kQr, Method::kSchur, Method::kSparseSchur}) {
    if (text == toString(m)) {
      *method = m;
      return true;
    }
  }
  return false;
}

namespace {

// 1. Checks that need nothing but the problem's bookkeeping; fills marg_set and the marginalized
//    size.
Status checkMarginalized(ceres::Problem* problem, const std::vector<double*>& blocks,
                         const MarginalizationOptions& options, MarginalizationSummary* summary,
                         std::unordered_set<const double*>* marg_set) {
  if (problem == nullptr) return invalid("problem is null");
  if (blocks.empty()) return invalid("no parameter block to marginalize");
  if (!(options.threshold >= 0) || !std::isfinite(options.threshold)) {
    return invalid(fmt::format("rank threshold {} is not a finite value >= 0", options.threshold));
  }
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    double* block = blocks[i];
    if (block == nullptr || !problem->HasParameterBlock(block)) {
      return invalid(fmt::format("block #{} ({}) is not a parameter block of the problem", i,
                                 static_cast<const void*>(block)));
    }
    if (!marg_set->insert(block).second)
      return invalid(fmt::format("block #{} is listed twice", i));
    if (problem->IsParameterBlockConstant(block)) {
      return invalid(fmt::format(
          "block #{} is constant: a constant block cannot be marginalized (make it variable, or "
          "keep it)",
          i));
    }
    for (int k = 0; k < problem->ParameterBlockSize(block); ++k) {
      if (problem->GetParameterLowerBound(block, k) > -std::numeric_limits<double>::max() ||
          problem->GetParameterUpperBound(block, k) < std::numeric_limits<double>::max()) {
        return invalid(fmt::format(
            "block #{} has a bound on coordinate {}: marginalization drops constraints on x_m "
            "(primer §5.4); remove the bounds first",
            i, k));
      }
    }
    summary->marginalized_dim += problem->ParameterBlockTangentSize(block);
  }
  summary->marginalized_blocks = static_cast<int>(blocks.size());
  return Status::Ok();
}

// ∂x_m and the Markov blanket.
struct Blanket {
  std::vector<ceres::ResidualBlockId> residuals;
  std::vector<double*> blocks;
  std::unordered_set<const double*> set;
};

// 2. In a deterministic order: residual blocks as the problem lists them, blanket blocks by first
//    appearance.
Blanket findBlanket(ceres::Problem* problem, const std::unordered_set<const double*>& marg_set,
                    MarginalizationSummary* summary) {
  std::vector<ceres::ResidualBlockId> all_residuals;
  problem->GetResidualBlocks(&all_residuals);
  Blanket b;
  std::unordered_set<const double*> constant_set;
  std::vector<double*> params;
  for (ceres::ResidualBlockId id : all_residuals) {
    problem->GetParameterBlocksForResidualBlock(id, &params);
    bool involves_marg = false;
    for (double* p : params) involves_marg = involves_marg || marg_set.count(p) > 0;
    if (!involves_marg) continue;
    b.residuals.push_back(id);
    for (double* p : params) {
      if (marg_set.count(p) > 0) continue;
      if (problem->IsParameterBlockConstant(p)) {
        constant_set.insert(p);
      } else if (b.set.insert(p).second) {
        b.blocks.push_back(p);
      }
    }
  }
  summary->removed_residual_blocks = static_cast<int>(b.residuals.size());
  summary->blanket_blocks = static_cast<int>(b.blocks.size());
  summary->constant_blanket_blocks = static_cast<int>(constant_set.size());
  summary->blanket = b.blocks;
  return b;
}

// 3. The blanket's manifolds and linearization points.
Status blanketLinearizationPoints(ceres::Problem* problem, const Blanket& blanket,
                                  const MarginalizationOptions& options,
                                  MarginalizationSummary* summary,
                                  std::vector<std::unique_ptr<BlockDifference>>* differences,
                                  std::vector<std::vector<double>>* x_lin) {
  for (std::size_t k = 0; k < blanket.blocks.size(); ++k) {
    double* block = blanket.blocks[k];
    const int size = problem->ParameterBlockSize(block);
    std::string what;
    std::unique_ptr<BlockDifference> difference =
        makeBlockDifference(problem->GetManifold(block), size, &what);
    if (difference == nullptr) return invalid(fmt::format("Markov blanket block #{}: {}", k, what));
    summary->blanket_dim += difference->tangentSize();
    differences->push_back(std::move(difference));
    const auto it = options.linearization_points.find(block);
    if (it != options.linearization_points.end()) {
      if (static_cast<int>(it->second.size()) != size) {
        return invalid(
            fmt::format("linearization point of blanket block #{} has {} values, the block has {}",
                        k, it->second.size(), size));
      }
      x_lin->push_back(it->second);
    } else {
      x_lin->emplace_back(block, block + size);
    }
  }
  for (const auto& [block, values] : options.linearization_points) {
    if (blanket.set.count(block) == 0) {
      return invalid(
          "a linearization point is given for a block that is not in the Markov blanket");
    }
  }
  return Status::Ok();
}

// 4. Linearization: f and [J_m | J_b] of ∂x_m, robustified (Triggs), in the tangent spaces.
Status linearize(ceres::Problem* problem, const std::vector<double*>& blocks,
                 const Blanket& blanket, const MarginalizationOptions& options,
                 MarginalizationSummary* summary, VecXd* f, ceres::CRSMatrix* crs) {
  const Clock::time_point eval_start = Clock::now();
  ceres::Problem::EvaluateOptions eval;
  eval.parameter_blocks = blocks;
  eval.parameter_blocks.insert(eval.parameter_blocks.end(), blanket.blocks.begin(),
                               blanket.blocks.end());
  eval.residual_blocks = blanket.residuals;
  eval.apply_loss_function = true;
  std::vector<double> f_values;
  bool evaluated = false;
  {
    const ValueSwap swap(options.linearization_points, blanket.blocks);
    evaluated = problem->Evaluate(eval, nullptr, &f_values, nullptr, crs);
  }
  summary->evaluate_ms = msSince(eval_start);
  if (!evaluated) {
    return Status::Error(
        Status::Code::kNotFinite,
        "marginalize: Ceres could not evaluate the residual blocks of the marginalized variables "
        "(a cost function failed or returned a non-finite residual or Jacobian)");
  }
  *f = Eigen::Map<const VecXd>(f_values.data(), static_cast<Eigen::Index>(f_values.size()));
  bool finite = f->allFinite();
  for (double v : crs->values) finite = finite && std::isfinite(v);
  if (!finite) {
    return Status::Error(Status::Code::kNotFinite,
                         "marginalize: non-finite residual or Jacobian at the "
                         "linearization point");
  }
  summary->residuals = crs->num_rows;
  return Status::Ok();
}

// 5. The square-root prior by the chosen method.
SqrtPriorResult squareRootPrior(const ceres::CRSMatrix& crs, const VecXd& f, int n_m,
                                const MarginalizationOptions& options) {
  if (options.method == Method::kSparseSchur) return viaSparseSchur(crs, f, n_m, options);
  MatXd J = MatXd::Zero(crs.num_rows, crs.num_cols);
  for (int row = 0; row < crs.num_rows; ++row) {
    for (int k = crs.rows[row]; k < crs.rows[row + 1]; ++k) J(row, crs.cols[k]) = crs.values[k];
  }
  return options.method == Method::kQr ? viaQr(J, f, n_m, options) : viaSchur(J, f, n_m, options);
}

}  // namespace

MarginalizationSummary marginalize(ceres::Problem* problem, const std::vector<double*>& blocks,
                                   const MarginalizationOptions& options) {
  const Clock::time_point start = Clock::now();
  MarginalizationSummary summary;
  summary.method = options.method;
  summary.threshold_mode = options.threshold_mode;
  summary.threshold = options.threshold;
  std::unordered_set<const double*> marg_set;
  summary.status = checkMarginalized(problem, blocks, options, &summary, &marg_set);
  if (!summary.status.ok()) return summary;
  const Blanket blanket = findBlanket(problem, marg_set, &summary);
  std::vector<std::unique_ptr<BlockDifference>> differences;
  std::vector<std::vector<double>> x_lin;
  summary.status =
      blanketLinearizationPoints(problem, blanket, options, &summary, &differences, &x_lin);
  if (!summary.status.ok()) return summary;
  VecXd f;
  ceres::CRSMatrix crs;
  summary.status = linearize(problem, blocks, blanket, options, &summary, &f, &crs);
  if (!summary.status.ok()) return summary;

  const Clock::time_point factor_start = Clock::now();
  SqrtPriorResult prior = squareRootPrior(crs, f, summary.marginalized_dim, options);
  summary.factorize_ms = msSince(factor_start);
  if (!prior.status.ok()) {
    summary.status =
        Status::Error(prior.status.code(), "marginalize (" + std::string(toString(options.method)) +
                                               "): " + prior.status.message());
    return summary;
  }
  summary.marg_rank = prior.marg_rank;
  summary.prior_rank = static_cast<int>(prior.R.rows());
  summary.prior_rows = summary.prior_rank;
  summary.condition_number = conditionNumber(prior.R);
  if (options.keep_factor) summary.factor = std::move(prior.factor);

  // 6. The problem changes only now: x_m and ∂x_m out, the prior in.
  for (double* block : blocks) problem->RemoveParameterBlock(block);
  if (summary.prior_rows > 0) {
    auto* cost = new MarginalizationPriorCost(std::move(differences), std::move(x_lin),
                                              std::move(prior.R), std::move(prior.r));
    summary.prior_cost = cost;
    summary.prior_block = problem->AddResidualBlock(cost, nullptr, blanket.blocks);
  }
  summary.total_ms = msSince(start);
  return summary;
}

}  // namespace marglab::ceres_marg
