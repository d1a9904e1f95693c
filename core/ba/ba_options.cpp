#include "core/ba/ba_options.h"

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <array>
#include <cmath>
#include <ctime>

namespace marglab {
namespace {

constexpr std::array<const char*, 9> kSolverNames = {
    "ns-f32", "ns-f64",         "nsx-f32",        "nsx-f64",     "sc-f32",
    "sc-f64", "ceres-implicit", "ceres-explicit", "ceres-sparse"};

void require(bool ok, const std::string& message, std::vector<Problem>* problems) {
  if (!ok) problems->push_back({ProblemKind::kUsage, "", 0, message});
}

double processCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

}  // namespace

BaClock::BaClock()
    : wall_start_(std::chrono::steady_clock::now()), cpu_start_(processCpuSeconds()) {}

double BaClock::wallSeconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start_).count();
}

double BaClock::cpuSeconds() const { return processCpuSeconds() - cpu_start_; }

const char* toString(BaSolver solver) { return kSolverNames[static_cast<size_t>(solver)]; }

std::vector<std::string> baSolverNames() { return {kSolverNames.begin(), kSolverNames.end()}; }

BaSolver parseBaSolver(const std::string& name) {
  for (size_t i = 0; i < kSolverNames.size(); ++i) {
    if (name == kSolverNames[i]) return static_cast<BaSolver>(i);
  }
  throw UsageError(
      fmt::format("--solver {}: expected one of {}", name, fmt::join(kSolverNames, ", ")));
}

bool isCeres(BaSolver solver) { return solver >= BaSolver::kCeresImplicit; }

const char* precisionOf(BaSolver solver) {
  return solver == BaSolver::kNsF32 || solver == BaSolver::kNsxF32 || solver == BaSolver::kScF32
             ? "f32"
             : "f64";
}

std::vector<Problem> validate(const BaOptions& o) {
  std::vector<Problem> problems;
  require(o.iterations >= 0, fmt::format("--iterations {}: expected ≥ 0", o.iterations), &problems);
  require(std::isfinite(o.huber_px) && o.huber_px >= 0,
          fmt::format("--huber {}: expected a threshold ≥ 0 pixels (0: none)", o.huber_px),
          &problems);
  require(std::isfinite(o.perturb_sigma) && o.perturb_sigma >= 0,
          fmt::format("--perturb {}: expected σ ≥ 0", o.perturb_sigma), &problems);
  require(std::isfinite(o.normalize_scale) && o.normalize_scale >= 0,
          fmt::format("--normalize {}: expected a scale > 0 (0: none)", o.normalize_scale),
          &problems);
  require(o.initial_lambda > 0 && o.min_lambda > 0 && o.min_lambda <= o.initial_lambda &&
              o.initial_lambda <= o.max_lambda,
          "LM damping: expected 0 < λ_min ≤ λ₀ ≤ λ_max", &problems);
  require(o.function_tolerance >= 0, "function tolerance: expected ≥ 0", &problems);
  require(o.cg.max_iterations > 0 && o.cg.eta > 0 && o.cg.eta < 1,
          "CG: expected at least one iteration and 0 < η < 1", &problems);
  require(o.threads >= 1, fmt::format("--threads {}: expected ≥ 1", o.threads), &problems);
  return problems;
}

}  // namespace marglab
