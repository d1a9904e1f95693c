#include "core/massspring/experiment.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include "core/common/error.h"

namespace marglab::massspring {
namespace {

using ceres_marg::Method;

using Clock = std::chrono::steady_clock;

double median(std::vector<double> v) { return summarize(std::move(v)).median; }

double maxAbsDiff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

// One method's Ceres split over the repetitions.
struct SplitSamples {
  std::vector<double> total, preprocess, evaluate, linear_solve;
  void push(const CeresSplit& s) {
    total.push_back(s.total_ms);
    preprocess.push_back(s.preprocess_ms);
    evaluate.push_back(s.evaluate_ms);
    linear_solve.push_back(s.linear_solve_ms);
  }
  CeresSplit medians() const {
    return {median(total), median(preprocess), median(evaluate), median(linear_solve)};
  }
};

// One two-stage method's timed quantities over the repetitions.
struct TwoSamples {
  std::vector<double> marg, stage1, stage2, total;
  SplitSamples stage1_split;
};

void pushTwo(const TwoStageResult& r, Method method, TwoSamples* samples) {
  if (!r.status.ok()) {
    throw InputError("massspring", 0,
                     fmt::format("two-stage ({}) failed: {}", ceres_marg::toString(method),
                                 r.status.toString()));
  }
  samples->marg.push_back(r.marginalize_ms);
  samples->stage1.push_back(r.stage1_ms);
  samples->stage2.push_back(r.stage2_ms);
  samples->total.push_back(r.total_ms);
  samples->stage1_split.push(r.stage1_split);
}

bool enoughReps(const ExperimentSettings& settings, int reps, Clock::time_point start) {
  if (settings.reps > 0) return reps >= settings.reps;
  const double elapsed_s = std::chrono::duration<double>(Clock::now() - start).count();
  return reps >= kMaxReps || (reps >= kMinAutoReps && elapsed_s >= settings.budget_s);
}

// Every solve of one grid, interleaved per repetition after an uncounted warm-up repetition.
GridTimes measureGrid(const MassSpringSystem& system, const ExperimentSettings& settings,
                      const std::vector<Method>& methods) {
  GridTimes g;
  g.twos.resize(methods.size());
  std::vector<double> single_ms;
  SplitSamples single_split;
  std::vector<TwoSamples> two(methods.size());
  const auto pass = [&](bool counted) {
    g.single.last = solveSingleStage(system, settings.iterations, settings.single_solver);
    if (counted) single_ms.push_back(g.single.last.solve_ms);
    if (counted) single_split.push(g.single.last.split);
    for (std::size_t i = 0; i < methods.size(); ++i) {
      g.twos[i].method = methods[i];
      g.twos[i].last = solveTwoStage(system, settings.iterations, methods[i]);
      TwoSamples scratch;
      pushTwo(g.twos[i].last, methods[i], counted ? &two[i] : &scratch);
    }
  };
  pass(false);  // first-touch allocations and cold caches are not what the table compares
  const Clock::time_point start = Clock::now();
  for (; !enoughReps(settings, g.reps, start); ++g.reps) pass(true);
  g.single.time = summarize(single_ms);
  g.single.split = single_split.medians();
  for (std::size_t i = 0; i < methods.size(); ++i) {
    TwoRow& t = g.twos[i];
    t.marg = summarize(two[i].marg);
    t.stage1 = summarize(two[i].stage1);
    t.stage2 = summarize(two[i].stage2);
    t.total = summarize(two[i].total);
    std::vector<double> ratio;
    for (int r = 0; r < g.reps; ++r) ratio.push_back(single_ms[r] / two[i].total[r]);
    t.speedup = summarize(ratio);
    t.stage1_split = two[i].stage1_split.medians();
    t.max_abs_diff = maxAbsDiff(t.last.x, g.single.last.x);
  }
  return g;
}

std::vector<ScalingRow> measureScaling(const ExperimentSettings& settings, const GridSpec& spec,
                                       const std::function<void(int)>& on_scaling_grid) {
  std::vector<ScalingRow> scaling;
  for (int n : settings.sizes) {
    if (on_scaling_grid) on_scaling_grid(n);
    GridSpec s = spec;
    s.n = n;
    const MassSpringSystem system = MassSpringSystem::grid(s);
    GridTimes g = measureGrid(system, settings, {settings.method});
    scaling.push_back(
        {n, system.num_masses, system.nonlinearMasses(), g.reps, g.single, g.twos.front()});
  }
  return scaling;
}

}  // namespace

void checkGridSize(const char* option, long n) {
  if (n < 4) {
    throw UsageError(
        fmt::format("{} {}: expected at least 4 (the corner sets must not overlap)", option, n));
  }
  if (n > kMaxGrid) {
    const double masses = static_cast<double>(n) * static_cast<double>(n);
    throw UsageError(
        fmt::format("{} {}: {:.0f} masses would take about {:.1f} GB of memory; expected at most "
                    "{} ({:.1f} GB)",
                    option, n, masses, masses * kBytesPerMass * 1e-9, kMaxGrid,
                    kMaxGrid * kMaxGrid * kBytesPerMass * 1e-9));
  }
}

std::vector<int> parseSizes(const std::string& list) {
  std::vector<int> sizes;
  std::stringstream in(list);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (item.empty()) continue;
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (*end != '\0') {
      throw UsageError("--sizes: '" + shortToken(item) + "' is not an integer grid size");
    }
    checkGridSize("--sizes", v);
    sizes.push_back(static_cast<int>(v));
  }
  return sizes;
}

void checkSettings(const ExperimentSettings& settings) {
  checkGridSize("--grid", settings.grid);
  if (settings.iterations < 1 || settings.iterations > kMaxIterations) {
    throw UsageError(fmt::format("--iterations {}: expected an integer in [1, {}]",
                                 settings.iterations, kMaxIterations));
  }
  if (settings.reps < 0 || settings.reps > kMaxReps) {
    throw UsageError(fmt::format("--reps {}: expected an integer in [0, {}] (0: automatic)",
                                 settings.reps, kMaxReps));
  }
  if (!(settings.budget_s > 0 && settings.budget_s <= kMaxBudgetS)) {
    throw UsageError(
        fmt::format("--budget {}: expected seconds in (0, {}]", settings.budget_s, kMaxBudgetS));
  }
  for (int n : settings.sizes) checkGridSize("--sizes", n);
  if (!denseFeasible(settings.grid) && settings.method != Method::kSparseSchur) {
    throw UsageError(
        fmt::format("--method {} builds a dense Jacobian; use sparse-schur above {}x{}",
                    ceres_marg::toString(settings.method), kMaxDenseGrid, kMaxDenseGrid));
  }
  if (settings.single_solver == SingleSolver::kSparseCholesky) return;
  std::vector<int> grids = settings.sizes;
  grids.push_back(settings.grid);
  for (int n : grids) {
    if (!denseFeasible(n)) {
      throw UsageError(fmt::format(
          "--single-solver {} builds a dense matrix of all masses: {}x{} is above {}x{}",
          toString(settings.single_solver), n, n, kMaxDenseGrid, kMaxDenseGrid));
    }
  }
}

Timing summarize(std::vector<double> v) {
  if (v.empty()) return {};
  std::sort(v.begin(), v.end());
  // The q-quantile, linear between order statistics (numpy's default).
  const auto quantile = [&v](double q) {
    const double pos = q * static_cast<double>(v.size() - 1);
    const std::size_t lo = static_cast<std::size_t>(pos);
    const std::size_t hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
  };
  return {quantile(0.5), quantile(0.25), quantile(0.75), v.front(), v.back()};
}

bool parseSingleSolver(const std::string& name, SingleSolver* solver) {
  for (SingleSolver s :
       {SingleSolver::kSparseCholesky, SingleSolver::kDenseCholesky, SingleSolver::kDenseQr}) {
    if (name == toString(s)) {
      *solver = s;
      return true;
    }
  }
  return false;
}

const char* toString(SingleSolver solver) {
  switch (solver) {
    case SingleSolver::kDenseCholesky:
      return "dense-cholesky";
    case SingleSolver::kDenseQr:
      return "dense-qr";
    case SingleSolver::kSparseCholesky:
      break;
  }
  return "sparse-cholesky";
}

bool denseFeasible(int n) { return n <= kMaxDenseGrid; }

const TwoRow& Measurements::main() const {
  const std::vector<TwoRow>& twos = compared.twos;
  return *std::find_if(twos.begin(), twos.end(),
                       [&](const TwoRow& t) { return t.method == settings.method; });
}

Measurements measure(const ExperimentSettings& settings,
                     const std::function<void(int n)>& on_scaling_grid) {
  GridSpec spec;
  spec.n = settings.grid;
  Measurements m{settings, MassSpringSystem::grid(spec), {}, {}};
  std::vector<Method> methods;
  for (Method two : {Method::kQr, Method::kSchur, Method::kSparseSchur}) {
    if (two == settings.method || denseFeasible(settings.grid)) methods.push_back(two);
  }
  m.compared = measureGrid(m.system, settings, methods);
  m.scaling = measureScaling(settings, spec, on_scaling_grid);
  return m;
}

}  // namespace marglab::massspring
