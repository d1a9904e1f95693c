#include "core/ba/ba_solver.h"

#include <fmt/core.h>

#include <cmath>
#include <limits>
#include <memory>

#include "core/ba/ceres_ba.h"
#include "core/ba/landmark_system.h"

namespace marglab {
namespace {

// The LM damping after a step (rootba's and Ceres' rule) and the loop's state.
struct Damping {
  double lambda;
  double vee = 2;
  void accepted(double rho, double min_lambda) {
    lambda = std::max(min_lambda, lambda * std::max(1.0 / 3, 1 - std::pow(2 * rho - 1, 3)));
    vee = 2;
  }
  void rejected() {
    lambda *= vee;
    vee *= 2;
  }
};

template <typename Scalar>
BalState<Scalar> applied(const BalState<Scalar>& state, const BaStep<Scalar>& step) {
  BalState<Scalar> moved = state;
  for (size_t c = 0; c < moved.cameras.size(); ++c) {
    moved.cameras[c].applyIncrement(step.delta_cameras[c]);
  }
  for (size_t l = 0; l < moved.points.size(); ++l) moved.points[l] += step.delta_points[l];
  return moved;
}

template <typename Scalar>
class LmRun {
 public:
  LmRun(const BalProblem& problem, const BaOptions& options, BaElimination elimination,
        BalState<double>* solution)
      : problem_(problem),
        solution_(solution),
        options_(options),
        loss_{options.huber_px},
        pool_(options.threads),
        system_(makeBaLinearSystem<Scalar>(problem, elimination, pool_)),
        state_(BalState<Scalar>::fromProblem(problem)),
        damping_{options.initial_lambda} {}

  BaResult run() {
    const CostSummary initial = evaluateCost(problem_.observations, state_, loss_);
    result_.initial_cost = cost_ = initial.cost;
    result_.num_behind_initial = initial.num_behind;
    record(0, 0, true, nullptr, "");
    bool relinearize = true;
    for (int it = 1; it <= options_.iterations && result_.status.empty(); ++it) {
      if (relinearize) {
        Status status = system_->linearize(state_, loss_);
        result_.num_fixed_points = system_->numFixedPoints();
        if (!status.ok()) return finish("failed", "linearization: " + status.message());
      }
      relinearize = tryStep(it);
    }
    if (result_.status.empty()) return finish("max_iterations", "");
    return finish(result_.status, result_.reason);
  }

 private:
  // One LM trial; true when the step was accepted (the next trial relinearizes).
  bool tryStep(int it) {
    BaStep<Scalar> step;
    const double lambda = damping_.lambda;
    Status status = system_->solve(Scalar(lambda), options_.cg, &step);
    double new_cost = std::numeric_limits<double>::quiet_NaN();
    BalState<Scalar> moved;
    if (status.ok()) {
      moved = applied(state_, step);
      const CostSummary c = evaluateCost(problem_.observations, moved, loss_);
      new_cost = c.cost;
      if (!c.finite || !std::isfinite(c.cost)) {
        status = Status::Error(Status::Code::kNotFinite, "non-finite cost after the step");
      }
    }
    const double model_decrease = -step.model_change;
    const double rho = (cost_ - new_cost) / model_decrease;
    if (!status.ok() || !(model_decrease > 0) || !(rho > 0)) {
      damping_.rejected();
      recordTrial(it, lambda, false, step, status.ok() ? "" : status.message());
      if (damping_.lambda > options_.max_lambda) {
        result_.status = "no_convergence";
        result_.reason =
            fmt::format("λ {:.1e} above its maximum {:.1e}", damping_.lambda, options_.max_lambda);
      }
      return false;
    }
    const double change = cost_ - new_cost;
    state_ = std::move(moved);
    cost_ = new_cost;
    damping_.accepted(rho, options_.min_lambda);
    recordTrial(it, lambda, true, step, "");
    if (std::abs(change) <= options_.function_tolerance * cost_) {
      result_.status = "converged";
      result_.reason = fmt::format("|Δcost| / cost = {:.2e} ≤ {:.0e}", change / cost_,
                                   options_.function_tolerance);
    }
    return true;
  }

  void recordTrial(int it, double lambda, bool accepted, const BaStep<Scalar>& step,
                   const std::string& message) {
    record(it, lambda, accepted, &step.cg, message);
  }

  void record(int it, double lambda, bool accepted, const CgSummary* cg,
              const std::string& message) {
    BaIteration row;
    row.iteration = it;
    row.cost = cost_;
    row.time_s = clock_.wallSeconds();
    row.cpu_s = clock_.cpuSeconds();
    row.lambda = lambda;
    row.accepted = accepted;
    row.cg_iterations = cg != nullptr ? cg->iterations : 0;
    row.ritz_min = cg != nullptr ? cg->ritz_min : std::numeric_limits<double>::quiet_NaN();
    row.ritz_max = cg != nullptr ? cg->ritz_max : std::numeric_limits<double>::quiet_NaN();
    row.message = message;
    result_.iterations.push_back(row);
  }

  BaResult finish(const std::string& status, const std::string& reason) {
    result_.status = status;
    result_.reason = reason;
    result_.final_cost = cost_;
    result_.num_behind_final = evaluateCost(problem_.observations, state_, loss_).num_behind;
    result_.total_time_s = clock_.wallSeconds();
    result_.total_cpu_s = clock_.cpuSeconds();
    if (solution_ != nullptr) {
      solution_->cameras.clear();
      for (const auto& camera : state_.cameras) {
        solution_->cameras.push_back(camera.template cast<double>());
      }
      solution_->points.clear();
      for (const auto& point : state_.points) {
        solution_->points.push_back(point.template cast<double>());
      }
    }
    return result_;
  }

  const BalProblem& problem_;
  BalState<double>* solution_;
  const BaOptions& options_;
  RobustLoss loss_;
  ThreadPool pool_;
  std::unique_ptr<BaLinearSystem<Scalar>> system_;  // the active ISA's, on pool_
  BalState<Scalar> state_;
  Damping damping_;
  double cost_ = 0;
  BaClock clock_;
  BaResult result_;
};

template <typename Scalar>
BaResult runLm(const BalProblem& problem, const BaOptions& options, BaElimination elimination,
               BalState<double>* solution) {
  return LmRun<Scalar>(problem, options, elimination, solution).run();
}

}  // namespace

BaResult solveBundleAdjustment(const BalProblem& problem, const BaOptions& options,
                               BalState<double>* solution) {
  switch (options.solver) {
    case BaSolver::kNsF64:
      return runLm<double>(problem, options, BaElimination::kNullspace, solution);
    case BaSolver::kNsxF64:
      return runLm<double>(problem, options, BaElimination::kNullspaceExplicit, solution);
    case BaSolver::kScF64:
      return runLm<double>(problem, options, BaElimination::kSchur, solution);
#if defined(MARGLAB_WITH_FLOAT)
    case BaSolver::kNsF32:
      return runLm<float>(problem, options, BaElimination::kNullspace, solution);
    case BaSolver::kNsxF32:
      return runLm<float>(problem, options, BaElimination::kNullspaceExplicit, solution);
    case BaSolver::kScF32:
      return runLm<float>(problem, options, BaElimination::kSchur, solution);
#endif
    default:
      if (isCeres(options.solver)) return solveWithCeres(problem, options, solution);
      throw UsageError(
          fmt::format("--solver {}: this build has no float numerics "
                      "(MARGLAB_FLOAT=OFF)",
                      toString(options.solver)));
  }
}

}  // namespace marglab
