#include "core/massspring/mass_spring.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <limits>
#include <memory>
#include <random>

#include "core/ceres_marg/sparse_cholesky.h"

namespace marglab::massspring {
namespace {

// The solving thread's CPU time, ms. The solves are single-threaded (Ceres num_threads = 1, serial
// CHOLMOD), and on a shared machine wall time also counts the other processes: a 20×20 single
// stage took 82 ms in one run and 5.2 ms in the next (issue #40).
double threadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

double msSince(double start_ms) { return threadCpuMs() - start_ms; }

using Mat22 = Eigen::Matrix<double, 2, 2, Eigen::RowMajor>;

void store(const Mat22& m, double* out) { std::copy(m.data(), m.data() + 4, out); }

// p = 2: r = √k e, e = z − x_i + x_j.
class LinearSpringCost final : public ceres::SizedCostFunction<2, 2, 2> {
 public:
  LinearSpringCost(const Eigen::Vector2d& z, double k) : z_(z), sqrt_k_(std::sqrt(k)) {}
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    const Eigen::Map<const Eigen::Vector2d> x_i(x[0]), x_j(x[1]);
    Eigen::Map<Eigen::Vector2d> r(residuals);
    r = sqrt_k_ * (z_ - x_i + x_j);
    if (jacobians != nullptr) {
      if (jacobians[0] != nullptr) store(-sqrt_k_ * Mat22::Identity(), jacobians[0]);
      if (jacobians[1] != nullptr) store(sqrt_k_ * Mat22::Identity(), jacobians[1]);
    }
    return true;
  }

 private:
  Eigen::Vector2d z_;
  double sqrt_k_;
};

// p = 4: r = √k ‖e‖ e so that ½‖r‖² = ½ k ‖e‖⁴;  ∂r/∂e = √k (‖e‖ I + e eᵀ/‖e‖) (→ 0 at e = 0).
class QuarticSpringCost final : public ceres::SizedCostFunction<2, 2, 2> {
 public:
  QuarticSpringCost(const Eigen::Vector2d& z, double k) : z_(z), sqrt_k_(std::sqrt(k)) {}
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    const Eigen::Map<const Eigen::Vector2d> x_i(x[0]), x_j(x[1]);
    const Eigen::Vector2d e = z_ - x_i + x_j;
    const double norm = e.norm();
    Eigen::Map<Eigen::Vector2d> r(residuals);
    r = sqrt_k_ * norm * e;
    if (jacobians != nullptr) {
      const Mat22 dr_de =
          norm > 0 ? Mat22(sqrt_k_ * (norm * Mat22::Identity() + e * e.transpose() / norm))
                   : Mat22(Mat22::Zero());
      if (jacobians[0] != nullptr) store(-dr_de, jacobians[0]);
      if (jacobians[1] != nullptr) store(dr_de, jacobians[1]);
    }
    return true;
  }

 private:
  Eigen::Vector2d z_;
  double sqrt_k_;
};

// r = √k (x − a).
class AnchorCost final : public ceres::SizedCostFunction<2, 2> {
 public:
  AnchorCost(const Eigen::Vector2d& a, double k) : a_(a), sqrt_k_(std::sqrt(k)) {}
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Eigen::Map<Eigen::Vector2d> r(residuals);
    r = sqrt_k_ * (Eigen::Map<const Eigen::Vector2d>(x[0]) - a_);
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      store(sqrt_k_ * Mat22::Identity(), jacobians[0]);
    }
    return true;
  }

 private:
  Eigen::Vector2d a_;
  double sqrt_k_;
};

void buildProblem(const MassSpringSystem& system, std::vector<double>* x, ceres::Problem* problem) {
  for (int i = 0; i < system.num_masses; ++i) problem->AddParameterBlock(x->data() + 2 * i, 2);
  for (const Spring& s : system.springs) {
    ceres::CostFunction* cost =
        s.p == 2 ? static_cast<ceres::CostFunction*>(new LinearSpringCost(s.z, s.k))
                 : new QuarticSpringCost(s.z, s.k);
    problem->AddResidualBlock(cost, nullptr, x->data() + 2 * s.i, x->data() + 2 * s.j);
  }
  for (const Anchor& a : system.anchors) {
    problem->AddResidualBlock(new AnchorCost(a.point, a.k), nullptr, x->data() + 2 * a.mass);
  }
}

int rejectedSteps(const ceres::Solver::Summary& summary) {
  int rejected = 0;
  for (const ceres::IterationSummary& it : summary.iterations) {
    rejected += it.iteration > 0 && !it.step_is_successful ? 1 : 0;
  }
  return rejected;
}

// Plain Gauss–Newton through Ceres: LM with μ = 1/radius = 1e-16, every step taken, no early stop.
ceres::Solver::Options gaussNewtonOptions(int iterations, ceres::LinearSolverType solver) {
  ceres::Solver::Options options;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.initial_trust_region_radius = 1e16;
  options.max_trust_region_radius = 1e16;
  options.max_num_iterations = iterations;
  options.function_tolerance = 0;
  options.gradient_tolerance = 0;
  options.parameter_tolerance = 0;
  // Any cost decrease accepts the step (Ceres requires ≥ 0). A rejected step would part the two
  // methods: their cost decreases differ (the full problem's includes the initial excess of the
  // linear residuals over their minimum). Rejections are counted and reported.
  options.min_relative_decrease = 0;
  options.linear_solver_type = solver;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;
  return options;
}

CeresSplit splitOf(const ceres::Solver::Summary& summary) {
  CeresSplit split;
  split.total_ms = 1e3 * summary.total_time_in_seconds;
  split.preprocess_ms = 1e3 * summary.preprocessor_time_in_seconds;
  split.evaluate_ms = 1e3 * (summary.residual_evaluation_time_in_seconds +
                             summary.jacobian_evaluation_time_in_seconds);
  split.linear_solve_ms = 1e3 * summary.linear_solver_time_in_seconds;
  return split;
}

ceres::LinearSolverType ceresSolver(SingleSolver solver) {
  switch (solver) {
    case SingleSolver::kDenseCholesky:
      return ceres::DENSE_NORMAL_CHOLESKY;
    case SingleSolver::kDenseQr:
      return ceres::DENSE_QR;
    case SingleSolver::kSparseCholesky:
      break;
  }
  return ceres::SPARSE_NORMAL_CHOLESKY;
}

// The residuals f of the springs that touch an eliminated mass at x, and their (constant) Jacobian
// J_m with respect to the eliminated masses (column marg_col[i] of mass i; -1: not eliminated).
void eliminatedResiduals(const MassSpringSystem& system, const std::vector<double>& x,
                         const std::vector<int>& marg_col, int n_m,
                         ceres_marg::SparseRowMatrix* J_m, VecXd* f) {
  std::vector<Eigen::Triplet<double, int>> triplets;
  std::vector<double> f_values;
  int row = 0;
  for (const Spring& s : system.springs) {
    if (marg_col[s.i] < 0 && marg_col[s.j] < 0) continue;
    const double sqrt_k = std::sqrt(s.k);
    const Eigen::Vector2d e = s.z - Eigen::Vector2d(x[2 * s.i], x[2 * s.i + 1]) +
                              Eigen::Vector2d(x[2 * s.j], x[2 * s.j + 1]);
    for (int d = 0; d < 2; ++d) {
      f_values.push_back(sqrt_k * e[d]);
      if (marg_col[s.i] >= 0) triplets.emplace_back(row + d, marg_col[s.i] + d, -sqrt_k);
      if (marg_col[s.j] >= 0) triplets.emplace_back(row + d, marg_col[s.j] + d, sqrt_k);
    }
    row += 2;
  }
  J_m->resize(row, n_m);
  J_m->setFromTriplets(triplets.begin(), triplets.end());
  J_m->makeCompressed();
  *f = Eigen::Map<const VecXd>(f_values.data(), row);
}

}  // namespace

MassSpringSystem MassSpringSystem::grid(const GridSpec& spec) {
  MassSpringSystem system;
  system.spec = spec;
  const int n = spec.n;
  system.num_masses = n * n;
  system.rest.resize(2 * static_cast<std::size_t>(n * n));
  const auto id = [n](int row, int col) { return row * n + col; };
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      system.rest[2 * id(row, col)] = col;
      system.rest[2 * id(row, col) + 1] = row;
    }
  }
  const auto rest = [&](int i) {
    return Eigen::Vector2d(system.rest[2 * i], system.rest[2 * i + 1]);
  };
  const std::vector<int> corners = {id(0, 0), id(0, n - 1), id(n - 1, 0), id(n - 1, n - 1)};
  const auto isCorner = [&](int i) {
    return std::find(corners.begin(), corners.end(), i) != corners.end();
  };
  system.in_nonlinear_set.assign(static_cast<std::size_t>(n * n), false);
  const auto addSpring = [&](int i, int j) {
    Spring s;
    s.i = i;
    s.j = j;
    s.p = isCorner(i) || isCorner(j) ? 4 : 2;
    s.k = s.p == 4 ? spec.k_nonlinear : spec.k_linear;
    s.z = rest(i) - rest(j);
    if (s.p == 4) system.in_nonlinear_set[i] = system.in_nonlinear_set[j] = true;
    system.springs.push_back(s);
  };
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      if (col + 1 < n) addSpring(id(row, col), id(row, col + 1));
      if (row + 1 < n) addSpring(id(row, col), id(row + 1, col));
    }
  }
  // Anchors pull the corners out of the rest shape: a stretch with some shear, asymmetric so the
  // final state is not a scaled copy of the grid.
  const std::vector<Eigen::Vector2d> pulls = {{-1.0, -0.5}, {0.8, -0.9}, {-0.6, 1.0}, {1.0, 0.7}};
  for (std::size_t c = 0; c < corners.size(); ++c) {
    system.anchors.push_back(
        {corners[c], rest(corners[c]) + spec.stretch * pulls[c], spec.k_anchor});
  }
  // Initial state: the rest grid plus portable uniform noise (raw 32-bit Mersenne twister
  // output). Gauss–Newton takes every step from here at all grid sizes (no trust-region
  // rejection), which the equality of the two methods' iterates relies on.
  std::mt19937 rng(spec.seed);
  system.initial = system.rest;
  for (double& v : system.initial) {
    v += spec.noise * (2.0 * (static_cast<double>(rng()) / 4294967296.0) - 1.0);
  }
  return system;
}

int MassSpringSystem::nonlinearMasses() const {
  return static_cast<int>(std::count(in_nonlinear_set.begin(), in_nonlinear_set.end(), true));
}

std::vector<double> MassSpringSystem::springEnergies(const std::vector<double>& x) const {
  std::vector<double> energies;
  energies.reserve(springs.size() + anchors.size());
  const auto pos = [&](int i) { return Eigen::Vector2d(x[2 * i], x[2 * i + 1]); };
  for (const Spring& s : springs) {
    energies.push_back(0.5 * s.k * std::pow((s.z - pos(s.i) + pos(s.j)).norm(), s.p));
  }
  for (const Anchor& a : anchors)
    energies.push_back(0.5 * a.k * (pos(a.mass) - a.point).squaredNorm());
  return energies;
}

double MassSpringSystem::energy(const std::vector<double>& x) const {
  double total = 0;
  for (double e : springEnergies(x)) total += e;
  return total;
}

SingleStageResult solveSingleStage(const MassSpringSystem& system, int iterations,
                                   SingleSolver solver) {
  SingleStageResult result;
  result.x = system.initial;
  ceres::Problem problem;
  buildProblem(system, &result.x, &problem);
  const ceres::Solver::Options options = gaussNewtonOptions(iterations, ceresSolver(solver));
  ceres::Solver::Summary summary;
  const double start = threadCpuMs();
  ceres::Solve(options, &problem, &summary);
  result.solve_ms = msSince(start);
  result.split = splitOf(summary);
  result.iterations = static_cast<int>(summary.iterations.size()) - 1;
  result.final_cost = summary.final_cost;
  result.termination = ceres::TerminationTypeToString(summary.termination_type);
  result.rejected_steps = rejectedSteps(summary);
  return result;
}

TwoStageResult solveTwoStage(const MassSpringSystem& system, int iterations,
                             ceres_marg::Method method) {
  TwoStageResult result;
  result.x = system.initial;
  ceres::Problem::Options problem_options;
  problem_options.enable_fast_removal = true;
  ceres::Problem problem(problem_options);
  buildProblem(system, &result.x, &problem);
  std::vector<double*> marg_blocks;
  std::vector<int> marg_col(static_cast<std::size_t>(system.num_masses), -1);
  for (int i = 0; i < system.num_masses; ++i) {
    if (system.in_nonlinear_set[i]) continue;
    marg_col[i] = 2 * static_cast<int>(marg_blocks.size());
    marg_blocks.push_back(result.x.data() + 2 * i);
  }

  // Stage 0: marginalize every mass outside 𝒩.
  const double start = threadCpuMs();
  ceres_marg::MarginalizationOptions marg_options;
  marg_options.method = method;
  marg_options.keep_factor = true;  // stage 2 solves with Λ_mm = J_mᵀJ_m, already factorized
  result.marginalization = ceres_marg::marginalize(&problem, marg_blocks, marg_options);
  result.marginalize_ms = msSince(start);
  if (!result.marginalization.status.ok()) {
    result.status = result.marginalization.status;
    return result;
  }

  // Stage 1: Gauss–Newton on 𝒩.
  const double stage1_start = threadCpuMs();
  const ceres::Solver::Options options =
      gaussNewtonOptions(iterations, ceres::DENSE_NORMAL_CHOLESKY);
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  result.stage1_ms = msSince(stage1_start);
  result.stage1_split = splitOf(summary);
  result.stage1_iterations = static_cast<int>(summary.iterations.size()) - 1;
  result.stage1_rejected_steps = rejectedSteps(summary);

  // Stage 2: with 𝒩 fixed the eliminated residuals are linear in x_m: one sparse solve.
  const double stage2_start = threadCpuMs();
  ceres_marg::SparseRowMatrix J_m;
  VecXd f;
  eliminatedResiduals(system, result.x, marg_col, 2 * static_cast<int>(marg_blocks.size()), &J_m,
                      &f);
  // J_m is constant (linear springs): the marginalization's factor of J_mᵀJ_m serves here
  // (sparse-schur); the dense methods keep none, so factorize.
  std::shared_ptr<const ceres_marg::SparseNormalCholesky> factor = result.marginalization.factor;
  if (factor == nullptr) {
    auto cholesky = std::make_shared<ceres_marg::SparseNormalCholesky>();
    result.status = cholesky->factorize(J_m);
    factor = cholesky;
  }
  MatXd delta;
  if (result.status.ok()) result.status = factor->solve(-(J_m.transpose() * f), &delta);
  if (!result.status.ok()) return result;
  for (std::size_t b = 0; b < marg_blocks.size(); ++b) {
    marg_blocks[b][0] += delta(2 * static_cast<Eigen::Index>(b), 0);
    marg_blocks[b][1] += delta(2 * static_cast<Eigen::Index>(b) + 1, 0);
  }
  result.stage2_ms = msSince(stage2_start);
  result.total_ms = msSince(start);
  result.final_cost = system.energy(result.x);
  return result;
}

}  // namespace marglab::massspring
