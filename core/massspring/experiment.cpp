#include "core/massspring/experiment.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include "core/common/error.h"

namespace marglab::massspring {
namespace {

using ceres_marg::Method;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0.0 : (n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

double maxAbsDiff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

SingleRow runSingle(const MassSpringSystem& system, int iterations, int reps) {
  SingleRow row;
  std::vector<double> ms;
  for (int r = 0; r < reps; ++r) {
    row.last = solveSingleStage(system, iterations);
    ms.push_back(row.last.solve_ms);
  }
  row.ms = median(ms);
  return row;
}

TwoRow runTwo(const MassSpringSystem& system, int iterations, int reps, Method method,
              const SingleRow& single) {
  TwoRow row;
  row.method = method;
  std::vector<double> marg, s1, s2, total;
  for (int r = 0; r < reps; ++r) {
    row.last = solveTwoStage(system, iterations, method);
    if (!row.last.status.ok()) {
      throw InputError("massspring", 0,
                       fmt::format("two-stage ({}) failed: {}", ceres_marg::toString(method),
                                   row.last.status.toString()));
    }
    marg.push_back(row.last.marginalize_ms);
    s1.push_back(row.last.stage1_ms);
    s2.push_back(row.last.stage2_ms);
    total.push_back(row.last.total_ms);
  }
  row.marg_ms = median(marg);
  row.stage1_ms = median(s1);
  row.stage2_ms = median(s2);
  row.total_ms = median(total);
  row.max_abs_diff = maxAbsDiff(row.last.x, single.last.x);
  return row;
}

std::vector<ScalingRow> measureScaling(const ExperimentSettings& settings, const GridSpec& spec,
                                       const std::function<void(int)>& on_scaling_grid) {
  std::vector<ScalingRow> scaling;
  for (int n : settings.sizes) {
    if (on_scaling_grid) on_scaling_grid(n);
    GridSpec s = spec;
    s.n = n;
    const MassSpringSystem system = MassSpringSystem::grid(s);
    ScalingRow row;
    row.n = n;
    row.masses = system.num_masses;
    row.reps = settings.reps > 0 ? settings.reps : autoReps(n);
    row.single = runSingle(system, settings.iterations, row.reps);
    row.two = runTwo(system, settings.iterations, row.reps, settings.method, row.single);
    scaling.push_back(row);
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
  for (int n : settings.sizes) checkGridSize("--sizes", n);
  if (!denseFeasible(settings.grid) && settings.method != Method::kSparseSchur) {
    throw UsageError(
        fmt::format("--method {} builds a dense Jacobian; use sparse-schur above {}x{}",
                    ceres_marg::toString(settings.method), kMaxDenseGrid, kMaxDenseGrid));
  }
}

int autoReps(int n) { return std::clamp(2500 / (n * n), 1, 20); }

bool denseFeasible(int n) { return n <= kMaxDenseGrid; }

const TwoRow& Measurements::main() const {
  return *std::find_if(twos.begin(), twos.end(),
                       [&](const TwoRow& t) { return t.method == settings.method; });
}

Measurements measure(const ExperimentSettings& settings,
                     const std::function<void(int n)>& on_scaling_grid) {
  GridSpec spec;
  spec.n = settings.grid;
  Measurements m{settings, MassSpringSystem::grid(spec), 0, {}, {}, {}};
  m.reps = settings.reps > 0 ? settings.reps : autoReps(settings.grid);
  m.single = runSingle(m.system, settings.iterations, m.reps);
  for (Method two : {Method::kQr, Method::kSchur, Method::kSparseSchur}) {
    if (two != settings.method && !denseFeasible(settings.grid)) continue;
    m.twos.push_back(runTwo(m.system, settings.iterations, m.reps, two, m.single));
  }
  m.scaling = measureScaling(settings, spec, on_scaling_grid);
  return m;
}

}  // namespace marglab::massspring
