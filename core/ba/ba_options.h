#pragma once
// Settings of one `marglab ba` run (docs/bundle_adjustment.md), validated in one place, and the
// record of its result.
//
// Defaults are rootba's (solver_options.hpp, bal_dataset_options.hpp): Levenberg–Marquardt with
// λ₀ = 1e-4 (initial trust region 1e4), λ ∈ [1e-16, 1e32], on failure λ ← v λ and v ← 2v, on
// success λ ← λ·max(1/3, 1 − (2ρ − 1)³) and v ← 2 (Nielsen's rule, as Ceres); function tolerance
// 1e-6 (stop when |Δcost| ≤ 1e-6 · cost); Schur-Jacobi PCG, at most 500 iterations, η = 0.1;
// Jacobian scaling on; 20 iterations; perturbation seed 38401. Every LM trial, accepted or not,
// counts as one iteration (rootba and Ceres count so).

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "core/ba/pcg.h"
#include "core/common/error.h"

namespace marglab {

enum class BaSolver {
  kNsF32,  // nullspace projection, kept implicit (core/linalg/landmark_block_implicit.h)
  kNsF64,
  kNsxF32,  // nullspace projection, the reduced rows explicit (rootba's storage, the estimator's)
  kNsxF64,
  kScF32,
  kScF64,
  kCeresImplicit,
  kCeresExplicit,
  kCeresSparse
};

const char* toString(BaSolver solver);
// The names of every solver, in enum order; parseBaSolver throws UsageError naming them.
std::vector<std::string> baSolverNames();
BaSolver parseBaSolver(const std::string& name);
bool isCeres(BaSolver solver);
const char* precisionOf(BaSolver solver);  // "f32" | "f64"

struct BaOptions {
  BaSolver solver = BaSolver::kNsF64;
  int iterations = 20;
  double huber_px = 0;       // 0: no robust loss
  double perturb_sigma = 0;  // camera centres and points, world units after normalization
  std::uint64_t seed = 38401;
  double normalize_scale = 0;  // 0: no normalization
  double initial_lambda = 1e-4;
  double min_lambda = 1e-16;
  double max_lambda = 1e32;
  double function_tolerance = 1e-6;
  CgOptions cg;
  int threads = 1;
};

// Every option out of range, as usage problems (core/common/error.h).
std::vector<Problem> validate(const BaOptions& options);

struct BaIteration {
  int iteration = 0;
  double cost = 0;
  double time_s = 0;  // since the start of the solve (after loading, normalizing, perturbing)
  double lambda = 0;  // the damping the step was tried with (Ceres: 1 / trust region radius)
  int cg_iterations = 0;
  bool accepted = false;
  double ritz_min = 0;  // NaN where not available (iteration 0, Ceres)
  double ritz_max = 0;
  std::string message;  // why a step failed ("" otherwise)
  // CPU time of the process (all its threads) since the start of the solve: beside time_s, the
  // measure that a machine shared with other work inflates least (one thread).
  double cpu_s = 0;
};

// Wall-clock and process CPU seconds since construction (the solve's clock).
class BaClock {
 public:
  BaClock();
  double wallSeconds() const;
  double cpuSeconds() const;

 private:
  std::chrono::steady_clock::time_point wall_start_;
  double cpu_start_ = 0;
};

struct BaResult {
  double initial_cost = 0;
  double final_cost = 0;
  std::vector<BaIteration> iterations;
  // "converged" (function tolerance), "max_iterations", "no_convergence" (λ above its maximum),
  // "failed" (a linearization that cannot go on): `reason` says which and why.
  std::string status;
  std::string reason;
  int num_behind_initial = 0;
  int num_behind_final = 0;
  int num_fixed_points = 0;  // points seen once: not eliminated, kept fixed (ns / sc)
  double total_time_s = 0;
  double total_cpu_s = 0;
};

}  // namespace marglab
