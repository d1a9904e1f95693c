#pragma once
// `marglab bench`: the key measurements of the benchmark suite in one process, side by side
// (timeSideBySide: every candidate in every round, best batch kept), on the shipped captured
// windows, plus whole runs (diagnostics off) of ns-qr-sqrt-f32 on EuRoC MH_01 and KITTI 00 and of
// sc-sc-sq-f64 on EuRoC MH_01 in child processes (their peak resident memory from wait4). Ratios
// are what carries over between machines; absolute times do not.

#include <array>
#include <string>
#include <vector>

#include "core/bench/ceres_window.h"
#include "core/bench/variant_bench.h"
#include "core/estimator/variant.h"

namespace marglab {

struct BenchOptions {
  int rounds = 5;
  double batch_s = 0.03;
  // Whole runs: frames per sequence (0: the whole sequence); no runs when run_exe is empty.
  int run_frames = 0;
  std::string run_exe;      // the marglab executable
  std::string work_dir;     // for the runs' results files
  std::string windows_dir;  // default: <datasets>/windows
  // Further variants timed beside ns-qr-sqrt-f32 on every window (core/bench/variant_bench.h).
  std::vector<Variant> variants;
  // Progress lines on stderr.
  bool verbose = false;
};

// One Ceres linear solver to convergence on one window, its best round.
struct CeresSolverTimes {
  std::string solver;  // "DENSE_SCHUR", "SPARSE_SCHUR", "ITERATIVE_SCHUR", "DENSE_QR"
  int iterations = 0;
  double seconds = 0;  // Solver::Summary total
  double cost = 0;
  CeresTimeSplit split;  // of the best round
};

// One Ceres solver over all windows.
struct CeresSolverTotals {
  std::string solver;
  int iterations = 0;
  double seconds = 0;
  double per_iteration_s = 0;  // Σ over windows of seconds / iterations
  double speedup = 0;          // per_iteration_s / marglab's
  CeresTimeSplit split;        // summed over windows
};

// The LM-iteration grid: landmark elimination × precision. ns is the paper's √ variant
// ns-qr-sqrt, sc its baseline sc-sc-sq (the marginalization method and storage go with the
// elimination, as in the paper's columns).
struct IterationCell {
  OptElimination elimination = OptElimination::kNullspace;
  Precision precision = Precision::kF32;  // kF32 or kF64
  Variant variant() const;                // ns-qr-sqrt-<precision> or sc-sc-sq-<precision>
};
// In the order they are timed and printed: ns-f32, ns-f64, sc-f32, sc-f64.
inline constexpr std::array<IterationCell, 4> kIterationCells = {
    {{OptElimination::kNullspace, Precision::kF32},
     {OptElimination::kNullspace, Precision::kF64},
     {OptElimination::kSchur, Precision::kF32},
     {OptElimination::kSchur, Precision::kF64}}};

// A value per precision and per cell of the grid.
struct PrecisionPair {
  double f32 = 0, f64 = 0;
  double& operator[](Precision p) { return p == Precision::kF32 ? f32 : f64; }
};
struct IterationTimes {
  PrecisionPair ns, sc;  // seconds
  double& operator[](const IterationCell& c) {
    return (c.elimination == OptElimination::kNullspace ? ns : sc)[c.precision];
  }
  IterationTimes& operator+=(const IterationTimes& o) {
    ns.f32 += o.ns.f32, ns.f64 += o.ns.f64, sc.f32 += o.sc.f32, sc.f64 += o.sc.f64;
    return *this;
  }
};

// One window's kernels with one ISA's code (core/linalg/isa.h), seconds; zero when the CPU lacks
// the ISA.
struct IsaTimes {
  IterationTimes iteration;           // LM iteration
  double qr_f32_s = 0, qr_f64_s = 0;  // landmark-block QR kernel
};

struct WindowTimes {
  std::string name;
  int landmarks = 0;
  // LM iteration (linearize + eliminate + solve) with the bench's ISA, seconds.
  IterationTimes iteration;
  double ns_mixed = 0;
  // To convergence with the window's LM settings, f64 (FEJ as captured).
  int marglab_iterations = 0;
  double marglab_s = 0;
  double marglab_cost = 0;
  std::vector<CeresSolverTimes> ceres;  // one per solver of the comparison
  // Marginalization event, seconds.
  double marg_qr_f32 = 0, marg_sc_f32 = 0, marg_qr_f64 = 0, marg_sc_f64 = 0;
  // Landmark-block QR kernel (flops of one pass over the window's landmarks).
  double qr_flops = 0;
  std::array<IsaTimes, 3> per_isa;  // indexed by Isa
};

struct WholeRun {
  std::string dataset, variant;
  int frames = 0;
  double data_s = 0, opt_s = 0, estimator_s = 0, realtime_factor = 0, peak_rss_mb = 0, wall_s = 0;
  std::string status;
};

struct BenchReport {
  std::string date_utc, git_sha, cpu, load_before, load_after;
  int rounds = 0;
  std::vector<WindowTimes> windows;
  std::string isa;                    // the ISA of the iteration, convergence and whole-run timings
  double peak_f32 = 0, peak_f64 = 0;  // machine peak (widest FMA the CPU has)
  std::string peak_isa;
  std::array<double, 3> isa_peak_f32{}, isa_peak_f64{};  // per ISA (0: not supported)
  std::vector<WholeRun> runs;
  int run_frames = 0;
  VariantBench variants;  // empty unless BenchOptions::variants named some
  // Derived.
  double speedup_ns_f32_over_sc_f64 = 0;
  double speedup_over_ceres_dense_schur = 0;  // per iteration, ns-f64 vs DENSE_SCHUR
  double speedup_over_ceres_sparse_schur = 0;
  double speedup_over_ceres_best = 0;  // over the fastest Ceres solver per iteration
  std::string ceres_best_solver;
  std::vector<CeresSolverTotals> ceres;
  std::array<double, 3> qr_gflops_f32_isa{}, qr_gflops_f64_isa{};
  double qr_gflops_f32 = 0, qr_gflops_f64 = 0;  // with the bench's ISA
  double qr_kernel_peak_fraction = 0;           // f32 kernel / f32 peak of the bench's ISA
};

BenchReport runBench(const BenchOptions& options);
std::string benchMarkdown(const BenchReport& report);
std::string benchJson(const BenchReport& report);

}  // namespace marglab
