#pragma once
// The measurements of `marglab massspring` (mass_spring.h has the maths): single-stage
// Gauss–Newton against two-stage optimization with marginalization on one grid, with every
// two-stage method that fits it, and the chosen method over a range of grid sizes.
//
// Every solve of a grid is repeated, the methods interleaved within each repetition (so a change of
// the machine's load falls on all of them alike), after one warm-up repetition that is not
// counted: `reps` times, or with reps = 0 until `budget_s` seconds are spent and at least
// kMinAutoReps repetitions ran (at most kMaxReps). Times are reported as median, quartiles and
// range (Timing; the problem's construction is not timed); the states are those of the last
// repetition, identical in every repetition. max_abs_diff is the largest coordinate difference
// between the two-stage and the single-stage final state.
// A two-stage solve that fails is an input error naming the method (the experiment's problems are
// well posed by construction, so a failure means a broken build, not a result).
//
// Limits: a grid side takes ~5.3 kB per mass (the sparse system, its factorization and the state
// of every iteration; measured at 100² to 600² masses: 0.10, 0.52 and 1.9 GB), so sides are kept
// to [4, kMaxGrid] (about 1.3 GB); repetitions and iterations are bounded so that a mistyped count
// is refused instead of running for days.

#include <functional>
#include <string>
#include <vector>

#include "core/ceres_marg/marginalize.h"
#include "core/massspring/mass_spring.h"

namespace marglab::massspring {

inline constexpr double kBytesPerMass = 5.3e3;
inline constexpr int kMaxGrid = 500;
inline constexpr int kMaxReps = 1000;        // 0: automatic (to the time budget)
inline constexpr int kMinAutoReps = 11;      // automatic: at least this many, for the quartiles
inline constexpr double kMaxBudgetS = 3600;  // --budget, seconds per grid
inline constexpr int kMaxIterations = 1000;  // Gauss–Newton iterations (the primer uses 10)
inline constexpr int kMaxDenseGrid = 30;     // qr / schur build an N × (n_m + n_b) dense Jacobian

struct ExperimentSettings {
  int grid = 5;            // masses per side of the compared grid
  std::vector<int> sizes;  // grid sides of the scaling table (may be empty)
  int iterations = 10;
  ceres_marg::Method method = ceres_marg::Method::kSparseSchur;
  SingleSolver single_solver = SingleSolver::kSparseCholesky;
  int reps = 0;           // 0: automatic, to budget_s
  double budget_s = 1.0;  // automatic repetitions: seconds of timed solves per grid
};

// Parses --single-solver (sparse-cholesky, dense-cholesky, dense-qr); false if unknown.
bool parseSingleSolver(const std::string& name, SingleSolver* solver);
const char* toString(SingleSolver solver);

// A grid side within [4, kMaxGrid], else a UsageError naming `option` and the memory it would take.
void checkGridSize(const char* option, long n);
// Grid sides from a comma-separated list (--sizes), each checked by checkGridSize.
std::vector<int> parseSizes(const std::string& list);
// Every range above and the method against the grid; throws UsageError naming the option.
void checkSettings(const ExperimentSettings& settings);

bool denseFeasible(int n);

// The spread of one timed quantity over the repetitions, ms.
struct Timing {
  double median = 0, q1 = 0, q3 = 0, min = 0, max = 0;
};
// Median, quartiles (linear interpolation between order statistics) and range of samples.
Timing summarize(std::vector<double> samples);

struct SingleRow {
  SingleStageResult last;
  Timing time;
  CeresSplit split;  // medians of Ceres' own split of the whole solve
};

struct TwoRow {
  ceres_marg::Method method = ceres_marg::Method::kQr;
  TwoStageResult last;
  Timing marg, stage1, stage2, total;
  Timing speedup;           // single stage / two-stage, paired within each repetition
  CeresSplit stage1_split;  // medians, Ceres' split of stage 1
  double max_abs_diff = 0;
};

// The solves of one grid.
struct GridTimes {
  int reps = 0;
  SingleRow single;
  std::vector<TwoRow> twos;
};

struct ScalingRow {
  int n = 0;
  int masses = 0;
  int nonlinear = 0;  // masses in N
  int reps = 0;
  SingleRow single;
  TwoRow two;
};

// Everything one experiment measures.
struct Measurements {
  ExperimentSettings settings;
  MassSpringSystem system;
  GridTimes compared;  // two-stage: qr, schur, sparse-schur — those that fit the grid
  std::vector<ScalingRow> scaling;
  const TwoRow& main() const;  // the two-stage row of settings.method
};

// Runs the experiment of checked settings; on_scaling_grid(n) is called before each grid side of
// the scaling table (progress).
Measurements measure(const ExperimentSettings& settings,
                     const std::function<void(int n)>& on_scaling_grid = {});

}  // namespace marglab::massspring
