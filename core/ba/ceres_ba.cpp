#include "core/ba/ceres_ba.h"

#include <ceres/ceres.h>
#include <glog/logging.h>

#include <limits>
#include <mutex>
#include <string>
#include <utility>

#include "core/ba/ba_state.h"

namespace marglab {
namespace {

// The latest glog warning while it lives (Ceres logs a failed linear solve only so).
class WarningSink : public google::LogSink {
 public:
  WarningSink() { google::AddLogSink(this); }
  ~WarningSink() override { google::RemoveLogSink(this); }
  WarningSink(const WarningSink&) = delete;
  WarningSink& operator=(const WarningSink&) = delete;

  void send(google::LogSeverity severity, const char*, const char*, int, const struct ::tm*,
            const char* message, size_t length) override {
    if (severity != google::GLOG_WARNING) return;
    const std::lock_guard<std::mutex> lock(mutex_);
    last_.assign(message, length);
  }
  std::string take() {
    const std::lock_guard<std::mutex> lock(mutex_);
    return std::exchange(last_, {});
  }

 private:
  std::mutex mutex_;
  std::string last_;
};

class Recorder : public ceres::IterationCallback {
 public:
  Recorder(BaResult* result, WarningSink* warnings) : result_(result), warnings_(warnings) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    BaIteration row;
    row.iteration = s.iteration;
    row.cost = s.cost;
    row.time_s = clock_.wallSeconds();
    row.cpu_s = clock_.cpuSeconds();
    row.lambda = 1.0 / s.trust_region_radius;
    row.cg_iterations = s.linear_solver_iterations;
    row.accepted = s.step_is_successful;
    row.ritz_min = row.ritz_max = std::numeric_limits<double>::quiet_NaN();
    const std::string warning = warnings_->take();
    if (!s.step_is_valid)
      row.message = warning.empty() ? "invalid step" : "invalid step: " + warning;
    result_->iterations.push_back(row);
    return ceres::SOLVER_CONTINUE;
  }
  const BaClock& clock() const { return clock_; }

 private:
  BaResult* result_;
  WarningSink* warnings_;
  BaClock clock_;
};

ceres::Solver::Options solverOptions(const BaOptions& options) {
  ceres::Solver::Options o;
  o.minimizer_type = ceres::TRUST_REGION;
  o.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  o.initial_trust_region_radius = 1.0 / options.initial_lambda;
  o.min_trust_region_radius = 1.0 / options.max_lambda;
  o.max_trust_region_radius = 1.0 / options.min_lambda;
  o.max_num_iterations = options.iterations;
  o.function_tolerance = options.function_tolerance;
  o.gradient_tolerance = 0;
  o.parameter_tolerance = 0;
  o.max_linear_solver_iterations = options.cg.max_iterations;
  o.eta = options.cg.eta;
  o.jacobi_scaling = true;
  o.num_threads = options.threads;
  o.logging_type = ceres::SILENT;
  o.linear_solver_type =
      options.solver == BaSolver::kCeresSparse ? ceres::SPARSE_SCHUR : ceres::ITERATIVE_SCHUR;
  o.preconditioner_type = ceres::SCHUR_JACOBI;
  o.use_explicit_schur_complement = options.solver == BaSolver::kCeresExplicit;
  return o;
}

std::string statusOf(ceres::TerminationType type) {
  switch (type) {
    case ceres::CONVERGENCE:
      return "converged";
    case ceres::NO_CONVERGENCE:
      return "max_iterations";
    default:
      return "failed";
  }
}

}  // namespace

BaResult solveWithCeres(const BalProblem& problem, const BaOptions& options,
                        BalState<double>* solution) {
  BalProblem variables = problem;  // Ceres updates the parameters in place
  ceres::Problem ceres_problem;
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (const BalObservation& obs : variables.observations) {
    ceres::LossFunction* loss =
        options.huber_px > 0 ? new ceres::HuberLoss(options.huber_px) : nullptr;
    ceres_problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<SnavelyResidual, 2, 9, 3>(new SnavelyResidual{obs.z}), loss,
        variables.cameras[obs.camera].data(), variables.points[obs.point].data());
  }
  for (Vec3<double>& X : variables.points) ordering->AddElementToGroup(X.data(), 0);
  for (Vec<double, 9>& c : variables.cameras) ordering->AddElementToGroup(c.data(), 1);
  ceres::Solver::Options solver_options = solverOptions(options);
  solver_options.linear_solver_ordering = ordering;
  BaResult result;
  WarningSink warnings;
  Recorder recorder(&result, &warnings);
  solver_options.callbacks.push_back(&recorder);
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &ceres_problem, &summary);
  const RobustLoss loss{options.huber_px};
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.status = statusOf(summary.termination_type);
  result.reason = summary.message;
  result.num_behind_initial =
      evaluateCost(problem.observations, BalState<double>::fromProblem(problem), loss).num_behind;
  result.num_behind_final =
      evaluateCost(variables.observations, BalState<double>::fromProblem(variables), loss)
          .num_behind;
  result.total_time_s = recorder.clock().wallSeconds();
  result.total_cpu_s = recorder.clock().cpuSeconds();
  if (solution != nullptr) *solution = BalState<double>::fromProblem(variables);
  return result;
}

void keepCeresWarningsOffStderr() {
  static std::once_flag once;
  std::call_once(once, [] {
    if (google::IsGoogleLoggingInitialized()) return;
    FLAGS_logtostderr = false;
    FLAGS_stderrthreshold = google::GLOG_ERROR;
    for (int severity = google::GLOG_INFO; severity < google::NUM_SEVERITIES; ++severity) {
      google::SetLogDestination(severity, "");  // no log files
    }
    google::InitGoogleLogging("marglab");
  });
}

}  // namespace marglab
