#include "core/bench/bench_report.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>

#include "core/bench/ceres_window.h"
#include "core/bench/perf_suite.h"
#include "core/bench/window_kernels.h"
#include "core/common/error.h"
#include "core/common/interrupt.h"
#include "core/common/json.h"
#include "core/common/subprocess.h"
#include "core/estimator/linearization_kernels.h"
#include "core/io/results_file.h"
#include "core/linalg/isa.h"
#include "core/linalg/landmark_block.h"
#include "core/pipeline/run.h"
#include "marglab/version.h"

namespace marglab {
namespace {

using Clock = std::chrono::steady_clock;

std::string firstLine(const std::string& path, const std::string& prefix = "") {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (prefix.empty() || line.rfind(prefix, 0) == 0) return line;
  }
  return "";
}

std::string loadAverage() {
  const std::string line = firstLine("/proc/loadavg");
  return line.substr(0, line.find(' ', line.find(' ', line.find(' ') + 1) + 1));
}

std::string cpuName() {
  std::string line = firstLine("/proc/cpuinfo", "model name");
  const size_t colon = line.find(':');
  return colon == std::string::npos ? "unknown" : line.substr(colon + 2);
}

std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%d %H:%M UTC", std::gmtime(&t));
  return buf;
}

void progress(const BenchOptions& o, const std::string& what) {
  if (o.verbose) fmt::print(stderr, "bench: {}\n", what);
}

template <typename Scalar>
std::function<void()> iterationOf(WindowKernels<Scalar>& k) {
  return [&k] {
    if (!k.iteration().ok()) throw InputError("", 0, "bench: an LM iteration failed");
  };
}

template <typename Scalar>
std::function<void()> margOf(WindowKernels<Scalar>& k, MargMethod m) {
  return [&k, m] {
    if (!k.marginalize(m).ok()) throw InputError("", 0, "bench: a marginalization failed");
  };
}

template <typename Scalar>
std::function<void()> qrOf(const LinearizationKernels<Scalar>& kernels,
                           const WindowKernels<Scalar>& k, const std::vector<PoseBlockMap>& maps) {
  return [qr = kernels.landmark_qr, &k, &maps] {
    if (!qr(k.landmarkJacobians(), maps)) throw InputError("", 0, "bench: a landmark QR failed");
  };
}

// A window's kernels with one ISA's code (a linearization keeps the ISA it was made with).
template <typename Scalar>
std::unique_ptr<WindowKernels<Scalar>> kernelsWith(Isa isa, const WindowSnapshot& w,
                                                   const Variant& variant) {
  const Isa active = activeIsa();
  setActiveIsa(isa);
  auto k = std::make_unique<WindowKernels<Scalar>>(w, variant);
  setActiveIsa(active);
  return k;
}

// The kernels of the iteration candidates, kept while they are timed.
struct IterationKernels {
  std::vector<std::unique_ptr<WindowKernels<float>>> f32;
  std::vector<std::unique_ptr<WindowKernels<double>>> f64;
};

// One LM iteration of a grid cell with one ISA's code, as a timing candidate.
std::function<void()> iterationCandidate(Isa isa, const WindowSnapshot& w, const IterationCell& c,
                                         IterationKernels& keep) {
  if (c.precision == Precision::kF32) {
    keep.f32.push_back(kernelsWith<float>(isa, w, c.variant()));
    return iterationOf(*keep.f32.back());
  }
  keep.f64.push_back(kernelsWith<double>(isa, w, c.variant()));
  return iterationOf(*keep.f64.back());
}

WholeRun wholeRun(const BenchOptions& o, const std::string& dataset, const std::string& variant) {
  WholeRun run;
  run.dataset = dataset;
  run.variant = variant;
  std::string name = dataset + "_" + variant;
  for (char& c : name) c = c == '/' ? '-' : c;
  const std::string out = (std::filesystem::path(o.work_dir) / ("run_" + name + ".h5")).string();
  std::vector<std::string> args = {o.run_exe,
                                   "run",
                                   "--dataset",
                                   dataset,
                                   "--variant",
                                   variant,
                                   "--no-diagnostics",
                                   "--isa",
                                   isaName(activeIsa()),
                                   "--frames",
                                   std::to_string(o.run_frames),
                                   "-o",
                                   out};
  const auto t0 = Clock::now();
  ChildSpec spec;
  spec.argv = std::move(args);
  spec.discard_output = true;
  const ChildResult child = runChild(spec);
  run.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  run.peak_rss_mb = static_cast<double>(child.usage.ru_maxrss) / 1024.0;
  if (child.stop_signal != 0) throw Interrupted(child.stop_signal);
  if (child.exit_code != 0) {
    run.status = fmt::format("failed (exit {})", child.exit_code);
    return run;
  }
  const SummaryValues s = ResultsReader(out, ResultsReader::Scope::kSummary).summary();
  run.frames = static_cast<int>(s.n_frames);
  run.data_s = s.duration_s;
  run.opt_s = s.t_opt_total_s;
  run.estimator_s = s.t_opt_total_s + s.t_marg_total_s;
  run.realtime_factor = s.realtime_factor;
  run.status = "ok";
  std::filesystem::remove(out);
  std::filesystem::remove(tumPathFor(out));
  return run;
}

double sum(const std::vector<WindowTimes>& w, double WindowTimes::*field) {
  double s = 0;
  for (const auto& x : w) s += x.*field;
  return s;
}

// The LM-iteration grid summed over the windows, with the bench's ISA.
IterationTimes iterationSum(const std::vector<WindowTimes>& w) {
  IterationTimes all;
  for (const auto& x : w) all += x.iteration;
  return all;
}

// The same with one ISA's code.
IterationTimes iterationSum(const std::vector<WindowTimes>& w, Isa isa) {
  IterationTimes all;
  for (const auto& x : w) all += x.per_isa[static_cast<size_t>(isa)].iteration;
  return all;
}

}  // namespace

namespace {

// One LM iteration: ns / sc × f32 / f64 with every ISA the CPU has, and ns-mixed (not a paper
// variant) with the bench's ISA, side by side.
void timeIterations(const WindowSnapshot& w, const BenchOptions& o, WindowTimes& t) {
  IterationKernels keep;
  std::vector<std::function<void()>> candidates;
  std::vector<std::pair<Isa, IterationCell>> timed;  // what candidates[k] is
  for (const Isa isa : availableIsas()) {
    for (const IterationCell& cell : kIterationCells) {
      candidates.push_back(iterationCandidate(isa, w, cell, keep));
      timed.emplace_back(isa, cell);
    }
  }
  const auto mixed = kernelsWith<double>(activeIsa(), w, Variant::parse("ns-qr-sqrt-mixed"));
  candidates.push_back(iterationOf(*mixed));
  keep.f32.front()->linearize();
  t.landmarks = keep.f32.front()->numLandmarkBlocks();
  const std::vector<double> it = timeSideBySide(candidates, o.rounds, o.batch_s);
  for (size_t k = 0; k < timed.size(); ++k) {
    t.per_isa[static_cast<size_t>(timed[k].first)].iteration[timed[k].second] = it[k];
  }
  t.iteration = t.per_isa[static_cast<size_t>(activeIsa())].iteration;
  t.ns_mixed = it.back();
}

// Marginalization, qr vs sc (square-root storage), side by side.
void timeMarginalization(const WindowSnapshot& w, const BenchOptions& o, WindowTimes& t) {
  WindowKernels<float> mq32(w, Variant::parse("ns-qr-sqrt-f32")),
      ms32(w, Variant::parse("ns-sc-sqrt-f32"));
  WindowKernels<double> mq64(w, Variant::parse("ns-qr-sqrt-f64")),
      ms64(w, Variant::parse("ns-sc-sqrt-f64"));
  std::vector<double> mg =
      timeSideBySide({margOf(mq32, MargMethod::kQr), margOf(ms32, MargMethod::kSchur),
                      margOf(mq64, MargMethod::kQr), margOf(ms64, MargMethod::kSchur)},
                     o.rounds, o.batch_s);
  t.marg_qr_f32 = mg[0];
  t.marg_sc_f32 = mg[1];
  t.marg_qr_f64 = mg[2];
  t.marg_sc_f64 = mg[3];
}

// The landmark QR kernel alone, f32 and f64, on the window's landmark blocks, with every ISA the
// CPU has.
void timeQrKernel(const WindowSnapshot& w, const BenchOptions& o, WindowTimes& t) {
  WindowKernels<float> ns32(w, Variant::parse("ns-qr-sqrt-f32"));
  WindowKernels<double> ns64(w, Variant::parse("ns-qr-sqrt-f64"));
  ns32.linearize();
  ns64.linearize();
  std::vector<PoseBlockMap> maps32, maps64;
  for (int i = 0; i < ns32.numLandmarkBlocks(); ++i) {
    maps32.push_back(ns32.blockMap(i));
    t.qr_flops += landmarkQrFlops(static_cast<int>(ns32.blockJp(i).rows()),
                                  static_cast<int>(ns32.blockJp(i).cols()) + 4);
  }
  for (int i = 0; i < ns64.numLandmarkBlocks(); ++i) maps64.push_back(ns64.blockMap(i));
  const std::vector<Isa> isas = availableIsas();
  std::vector<std::function<void()>> candidates;
  for (const Isa isa : isas) {
    candidates.push_back(qrOf(kernelsOf(isa).f32, ns32, maps32));
    candidates.push_back(qrOf(kernelsOf(isa).f64, ns64, maps64));
  }
  const std::vector<double> qr = timeSideBySide(candidates, o.rounds, o.batch_s);
  for (size_t i = 0; i < isas.size(); ++i) {
    t.per_isa[static_cast<size_t>(isas[i])].qr_f32_s = qr[2 * i];
    t.per_isa[static_cast<size_t>(isas[i])].qr_f64_s = qr[2 * i + 1];
  }
}

// To convergence: marglab ns-f64 optimize() vs Ceres with each linear solver, each round in turn,
// best per candidate (Ceres: its Solver::Summary total time, with the split of that round).
void timeToConvergence(const NamedWindow& nw, const BenchOptions& o, WindowTimes& t) {
  const WindowSnapshot& w = nw.window;
  WindowKernels<double> full(w, Variant::parse("ns-qr-sqrt-f64"));
  t.marglab_s = 1e300;
  const std::vector<ceres::LinearSolverType> solvers = {ceres::DENSE_SCHUR, ceres::SPARSE_SCHUR,
                                                        ceres::ITERATIVE_SCHUR, ceres::DENSE_QR};
  t.ceres.assign(solvers.size(), CeresSolverTimes{});
  for (size_t k = 0; k < solvers.size(); ++k) {
    t.ceres[k].solver = ceres::LinearSolverTypeToString(solvers[k]);
    t.ceres[k].seconds = 1e300;
  }
  for (int round = 0; round < o.rounds; ++round) {
    const auto t0 = Clock::now();
    double cost = 0;
    if (!full.optimizeFull(&t.marglab_iterations, &cost).ok()) {
      throw InputError("", 0, "bench: marglab optimize() failed on " + nw.name);
    }
    t.marglab_s = std::min(t.marglab_s, std::chrono::duration<double>(Clock::now() - t0).count());
    t.marglab_cost = cost;
    for (size_t k = 0; k < solvers.size(); ++k) {
      CeresWindowOptions co;
      co.linear_solver = solvers[k];
      const CeresWindowResult c = solveWindowWithCeres(w, co);
      if (!c.ok) throw InputError("", 0, "bench: Ceres failed on " + nw.name + ": " + c.message);
      CeresSolverTimes& best = t.ceres[k];
      if (c.seconds < best.seconds) {
        best.seconds = c.seconds;
        best.split = c.split;
      }
      best.iterations = c.iterations;
      best.cost = c.cost_final;
    }
  }
}

// Per solver over all windows, and the per-iteration speedups of marglab over each.
void ceresTotals(BenchReport& r) {
  double m_it = 0;
  for (const auto& t : r.windows) m_it += t.marglab_s / std::max(1, t.marglab_iterations);
  r.ceres.clear();
  for (size_t k = 0; !r.windows.empty() && k < r.windows.front().ceres.size(); ++k) {
    CeresSolverTotals total;
    total.solver = r.windows.front().ceres[k].solver;
    for (const auto& t : r.windows) {
      const CeresSolverTimes& c = t.ceres[k];
      total.iterations += c.iterations;
      total.seconds += c.seconds;
      total.per_iteration_s += c.seconds / std::max(1, c.iterations);
      total.split.preprocessor_s += c.split.preprocessor_s;
      total.split.minimizer_s += c.split.minimizer_s;
      total.split.linear_solver_s += c.split.linear_solver_s;
      total.split.residual_s += c.split.residual_s;
      total.split.jacobian_s += c.split.jacobian_s;
      total.split.postprocessor_s += c.split.postprocessor_s;
    }
    total.speedup = total.per_iteration_s / m_it;
    if (total.solver == "DENSE_SCHUR") r.speedup_over_ceres_dense_schur = total.speedup;
    if (total.solver == "SPARSE_SCHUR") r.speedup_over_ceres_sparse_schur = total.speedup;
    if (r.ceres_best_solver.empty() || total.speedup < r.speedup_over_ceres_best) {
      r.speedup_over_ceres_best = total.speedup;
      r.ceres_best_solver = total.solver;
    }
    r.ceres.push_back(total);
  }
}

}  // namespace

BenchReport runBench(const BenchOptions& o) {
  BenchReport r;
  r.date_utc = utcNow();
  r.git_sha = MARGLAB_GIT_SHA;
  r.cpu = cpuName();
  r.load_before = loadAverage();
  r.rounds = o.rounds;
  r.isa = isaName(activeIsa());
  const std::vector<NamedWindow> windows = loadWindows(o.windows_dir);
  if (windows.empty()) throw InputError(o.windows_dir, 0, "bench: no captured windows");

  for (const NamedWindow& nw : windows) {
    progress(o, nw.name);
    WindowTimes t;
    t.name = nw.name;
    timeIterations(nw.window, o, t);
    timeMarginalization(nw.window, o, t);
    timeQrKernel(nw.window, o, t);
    timeToConvergence(nw, o, t);
    r.windows.push_back(t);
    if (!o.variants.empty()) {
      r.variants.windows.push_back(nw.name);
      r.variants.times.push_back(timeVariants(nw.window, o.variants, o.rounds, o.batch_s));
    }
  }
  progress(o, "single-core peak");
  const FmaPeak p32 = machinePeak(true, 0.3), p64 = machinePeak(false, 0.3);
  r.peak_f32 = p32.gflops;
  r.peak_f64 = p64.gflops;
  r.peak_isa = p32.isa;
  for (const Isa isa : availableIsas()) {
    r.isa_peak_f32[static_cast<size_t>(isa)] = isaPeak(isa, true, 0.3).gflops;
    r.isa_peak_f64[static_cast<size_t>(isa)] = isaPeak(isa, false, 0.3).gflops;
  }

  r.run_frames = o.run_frames;
  if (!o.run_exe.empty()) {
    const std::pair<const char*, const char*> runs[] = {{"euroc/MH_01_easy", "ns-qr-sqrt-f32"},
                                                        {"kitti/00", "ns-qr-sqrt-f32"},
                                                        {"euroc/MH_01_easy", "sc-sc-sq-f64"}};
    for (const auto& [dataset, variant] : runs) {
      progress(o, fmt::format("whole run {} {} ({} frames)", dataset, variant,
                              o.run_frames > 0 ? std::to_string(o.run_frames) : "all"));
      r.runs.push_back(wholeRun(o, dataset, variant));
    }
  }
  r.load_after = loadAverage();

  const auto& W = r.windows;
  const IterationTimes all = iterationSum(W);
  r.speedup_ns_f32_over_sc_f64 = all.sc.f64 / all.ns.f32;
  ceresTotals(r);
  const double flops = sum(W, &WindowTimes::qr_flops);
  for (const Isa isa : availableIsas()) {
    const size_t i = static_cast<size_t>(isa);
    double s32 = 0, s64 = 0;
    for (const auto& t : W) {
      s32 += t.per_isa[i].qr_f32_s;
      s64 += t.per_isa[i].qr_f64_s;
    }
    r.qr_gflops_f32_isa[i] = flops / s32 * 1e-9;
    r.qr_gflops_f64_isa[i] = flops / s64 * 1e-9;
  }
  const size_t active = static_cast<size_t>(activeIsa());
  r.qr_gflops_f32 = r.qr_gflops_f32_isa[active];
  r.qr_gflops_f64 = r.qr_gflops_f64_isa[active];
  r.qr_kernel_peak_fraction = r.qr_gflops_f32 / r.isa_peak_f32[active];
  return r;
}

namespace {

// The to-convergence comparison: per window, then per solver with Ceres' own time split.
std::string ceresMarkdown(const BenchReport& r) {
  std::string s =
      "## To convergence, f64, the window's LM settings: marglab ns-qr-sqrt-f64 vs "
      "Ceres\n\nPer solver: iterations · µs per iteration.\n\n| window | marglab it · µs/it";
  std::string rule = "|---|---:";
  for (const auto& c : r.ceres) {
    s += " | " + c.solver + " it · µs/it";
    rule += "|---:";
  }
  s += " | final cost marglab / Ceres solvers |\n" + rule + "|---|\n";
  for (const auto& t : r.windows) {
    s += fmt::format("| {} | {} · {:.0f}", t.name, t.marglab_iterations,
                     t.marglab_s / std::max(1, t.marglab_iterations) * 1e6);
    std::string costs = fmt::format("{:.6f}", t.marglab_cost);
    for (const auto& c : t.ceres) {
      s += fmt::format(" | {} · {:.0f}", c.iterations, c.seconds / std::max(1, c.iterations) * 1e6);
      costs += fmt::format(" / {:.6f}", c.cost);
    }
    s += " | " + costs + " |\n";
  }
  s += "\nPer solver, all windows: Ceres' own time split (Solver::Summary; linear solver, residual "
       "and Jacobian evaluation are parts of the minimizer), and marglab's per-iteration speedup "
       "(sum over windows of time per iteration).\n\n"
       "| solver | iterations | total ms | µs/it | speedup | preprocessor ms | minimizer ms | "
       "linear solver ms | residuals ms | Jacobians ms | postprocessor ms |\n"
       "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const auto& c : r.ceres) {
    s += fmt::format(
        "| {} | {} | {:.2f} | {:.0f} | {:.2f}× | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | "
        "{:.2f} |\n",
        c.solver, c.iterations, c.seconds * 1e3, c.per_iteration_s * 1e6, c.speedup,
        c.split.preprocessor_s * 1e3, c.split.minimizer_s * 1e3, c.split.linear_solver_s * 1e3,
        c.split.residual_s * 1e3, c.split.jacobian_s * 1e3, c.split.postprocessor_s * 1e3);
  }
  s += fmt::format(
      "\nFastest Ceres solver per iteration: {} (marglab **{:.2f}×** faster); DENSE_SCHUR "
      "**{:.2f}×**. An iteration is one linearization for marglab (possibly several λ trials) and "
      "one trust-region step for Ceres; Ceres' time is its Solver::Summary total (preprocessing "
      "included, problem construction not). ITERATIVE_SCHUR uses the SCHUR_JACOBI "
      "preconditioner.\n\n",
      r.ceres_best_solver, r.speedup_over_ceres_best, r.speedup_over_ceres_dense_schur);
  return s;
}

// LM iteration (all windows summed) and the landmark QR kernel against the peak, per ISA.
// A field of the whole run of (dataset, variant); NaN when it did not run or failed.
double wholeRunField(const BenchReport& r, const std::string& dataset, const std::string& variant,
                     double WholeRun::*field) {
  for (const auto& run : r.runs) {
    if (run.dataset == dataset && run.variant == variant && run.status == "ok") return run.*field;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

// opt(sc-sc-sq-f64) / opt(ns-qr-sqrt-f32) of the whole EuRoC MH_01 runs (issue #21's whole-run
// ratio; the paper's 1.9x).
double wholeRunOptRatio(const BenchReport& r) {
  return wholeRunField(r, "euroc/MH_01_easy", "sc-sc-sq-f64", &WholeRun::opt_s) /
         wholeRunField(r, "euroc/MH_01_easy", "ns-qr-sqrt-f32", &WholeRun::opt_s);
}

std::string isaMarkdown(const BenchReport& r) {
  std::string s =
      "## Per ISA: one LM iteration (all windows, µs) and the landmark-block Householder QR "
      "kernel (LandmarkBlockNs::setFromJacobians, GFLOP/s and fraction of the ISA's single-core "
      "peak)\n\n| isa | ns-f32 | ns-f64 | sc-f32 | sc-f64 | sc-f64 / ns-f32 | QR f32 | peak f32 | "
      "fraction | QR f64 | peak f64 | fraction |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const Isa isa : availableIsas()) {
    const size_t i = static_cast<size_t>(isa);
    const IterationTimes all = iterationSum(r.windows, isa);
    s += fmt::format(
        "| {} | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {:.2f} | {:.2f} | {:.1f} | {:.1f} % | {:.2f} | "
        "{:.1f} | {:.1f} % |\n",
        isaName(isa), all.ns.f32 * 1e6, all.ns.f64 * 1e6, all.sc.f32 * 1e6, all.sc.f64 * 1e6,
        all.sc.f64 / all.ns.f32, r.qr_gflops_f32_isa[i], r.isa_peak_f32[i],
        100 * r.qr_gflops_f32_isa[i] / r.isa_peak_f32[i], r.qr_gflops_f64_isa[i], r.isa_peak_f64[i],
        100 * r.qr_gflops_f64_isa[i] / r.isa_peak_f64[i]);
  }
  s += fmt::format(
      "\nPeaks: independent FMA chains in registers (sse2: multiply + add); machine peak {} "
      "{:.1f} / {:.1f} GFLOP/s (f32 / f64).\n",
      r.peak_isa, r.peak_f32, r.peak_f64);
  return s;
}

// A measured figure as the JSON keeps it: 6 significant digits (null when not measured).
double figure6(double x) { return roundedTo(x, 6); }

// The LM-iteration grid in µs, keyed lm_iteration_us_<ns|sc>_<f32|f64>.
void iterationJson(Json& j, const IterationTimes& t) {
  j["lm_iteration_us_ns_f32"] = figure6(t.ns.f32 * 1e6);
  j["lm_iteration_us_ns_f64"] = figure6(t.ns.f64 * 1e6);
  j["lm_iteration_us_sc_f32"] = figure6(t.sc.f32 * 1e6);
  j["lm_iteration_us_sc_f64"] = figure6(t.sc.f64 * 1e6);
}

// What the whole-run figures cover.
std::string runFramesNote(const BenchReport& r) {
  if (r.runs.empty()) return "no whole runs";
  return r.run_frames > 0 ? fmt::format("whole-run RTFs over the first {} frames", r.run_frames)
                          : "whole sequences";
}

// The JSON object of per-ISA figures.
Json isaJson(const BenchReport& r) {
  Json all = Json::object();
  for (const Isa isa : availableIsas()) {
    const size_t i = static_cast<size_t>(isa);
    Json& j = all[isaName(isa)];
    iterationJson(j, iterationSum(r.windows, isa));
    j["qr_kernel_gflops_f32"] = figure6(r.qr_gflops_f32_isa[i]);
    j["qr_kernel_gflops_f64"] = figure6(r.qr_gflops_f64_isa[i]);
    j["peak_gflops_f32"] = figure6(r.isa_peak_f32[i]);
    j["peak_gflops_f64"] = figure6(r.isa_peak_f64[i]);
  }
  return all;
}

// Microseconds with one decimal.
std::string us(double seconds) { return fmt::format("{:.1f}", seconds * 1e6); }

// The title and one LM iteration per captured window and variant.
std::string iterationMarkdown(const BenchReport& r) {
  std::string s;
  s += fmt::format(
      "# marglab bench\n\n{} · git {} · {} · isa {} · load average {} (start) / {} (end) · "
      "best of {} rounds, candidates interleaved\n\n",
      r.date_utc, r.git_sha, r.cpu, r.isa, r.load_before, r.load_after, r.rounds);
  s += "## One LM iteration on the captured windows (linearize + eliminate + solve), µs, " + r.isa +
       "\n\n";
  s += "| window | landmarks | ns-f32 | ns-f64 | sc-f32 | sc-f64 | ns-mixed | sc-f64 / ns-f32 |\n"
       "|---|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const auto& t : r.windows) {
    const IterationTimes& i = t.iteration;
    s += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {:.2f} |\n", t.name, t.landmarks,
                     us(i.ns.f32), us(i.ns.f64), us(i.sc.f32), us(i.sc.f64), us(t.ns_mixed),
                     i.sc.f64 / i.ns.f32);
  }
  const IterationTimes all = iterationSum(r.windows);
  s += fmt::format("| **all** | | {} | {} | {} | {} | {} | **{:.2f}** |\n\n", us(all.ns.f32),
                   us(all.ns.f64), us(all.sc.f32), us(all.sc.f64),
                   us(sum(r.windows, &WindowTimes::ns_mixed)), r.speedup_ns_f32_over_sc_f64);
  s += "ns = ns-qr-sqrt (nullspace projection), sc = sc-sc-sq (Schur complement, Hessian "
       "prior), ns-mixed = ns-qr-sqrt-mixed (landmarks eliminated in f32, the rest in f64).\n\n";
  return s;
}

std::string margEventMarkdown(const BenchReport& r) {
  std::string s;
  s += "## One marginalization event (oldest keyframe + its landmarks; VIO: + oldest speed-bias), "
       "µs\n\n";
  s += "| window | qr-f32 | sc-f32 | qr-f64 | sc-f64 |\n|---|---:|---:|---:|---:|\n";
  for (const auto& t : r.windows) {
    s += fmt::format("| {} | {} | {} | {} | {} |\n", t.name, us(t.marg_qr_f32), us(t.marg_sc_f32),
                     us(t.marg_qr_f64), us(t.marg_sc_f64));
  }
  return s;
}

std::string wholeRunsMarkdown(const BenchReport& r) {
  std::string s;
  if (!r.runs.empty()) {
    s += fmt::format("## Whole runs: diagnostics off, one core ({})\n\n",
                     r.run_frames > 0 ? fmt::format("first {} frames", r.run_frames)
                                      : std::string("whole sequences"));
    s += "| sequence | variant | status | frames | data s | optimization s | estimator s | "
         "real-time factor | peak RSS MB | wall s |\n"
         "|---|---|---|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const auto& run : r.runs) {
      s += fmt::format(
          "| {} | {} | {} | {} | {:.1f} | {:.2f} | {:.2f} | {:.1f}× | {:.0f} | {:.1f} |\n",
          run.dataset, run.variant, run.status, run.frames, run.data_s, run.opt_s, run.estimator_s,
          run.realtime_factor, run.peak_rss_mb, run.wall_s);
    }
    s += "\nReal-time factor = data duration / (optimization + marginalization time) as in the "
         "results file; peak RSS of the whole `marglab run` process (simulation included).\n\n";
  }
  return s;
}

// The targets of issue #21, each measured, met or not.
std::string targetsMarkdown(const BenchReport& r) {
  std::string s;
  auto figure = [](double x, int digits, const char* unit) {
    return std::isfinite(x) ? fmt::format("{:.{}f}{}", x, digits, unit) : std::string("–");
  };
  // A target whose figure was not measured (e.g. --no-runs) is neither met nor missed.
  auto met = [](double x, bool b) {
    return !std::isfinite(x) ? "not measured" : b ? "yes" : "**no**";
  };
  const double rtf_euroc =
      wholeRunField(r, "euroc/MH_01_easy", "ns-qr-sqrt-f32", &WholeRun::realtime_factor);
  const double rtf_kitti =
      wholeRunField(r, "kitti/00", "ns-qr-sqrt-f32", &WholeRun::realtime_factor);
  const double rss = wholeRunField(r, "euroc/MH_01_easy", "ns-qr-sqrt-f32", &WholeRun::peak_rss_mb);
  const double opt_ratio = wholeRunOptRatio(r);
  s += "## Targets (issue #21)\n\n| target | measured | met |\n|---|---:|---|\n";
  s += fmt::format("| ns-f32 per iteration ≥ 1.9× faster than sc-f64 | {:.2f}× | {} |\n",
                   r.speedup_ns_f32_over_sc_f64,
                   met(r.speedup_ns_f32_over_sc_f64, r.speedup_ns_f32_over_sc_f64 >= 1.9));
  s += fmt::format(
      "| whole run EuRoC MH_01: opt(sc-sc-sq-f64) / opt(ns-qr-sqrt-f32) ≥ 1.7× | {} | {} |\n",
      figure(opt_ratio, 2, "×"), met(opt_ratio, opt_ratio >= 1.7));
  s += fmt::format(
      "| ns-f64 per iteration ≥ 3× faster than Ceres' fastest solver ({}) | {:.2f}× | "
      "{} |\n",
      r.ceres_best_solver, r.speedup_over_ceres_best,
      met(r.speedup_over_ceres_best, r.speedup_over_ceres_best >= 3));
  s += fmt::format("| QR kernel ≥ 30 % of the single-core peak of its ISA | {:.1f} % | {} |\n",
                   100 * r.qr_kernel_peak_fraction,
                   met(r.qr_kernel_peak_fraction, r.qr_kernel_peak_fraction >= 0.3));
  s += fmt::format("| RTF EuRoC MH_01 ≥ 20× | {} | {} |\n", figure(rtf_euroc, 1, "×"),
                   met(rtf_euroc, rtf_euroc >= 20));
  s += fmt::format("| RTF KITTI 00 ≥ 40× | {} | {} |\n", figure(rtf_kitti, 1, "×"),
                   met(rtf_kitti, rtf_kitti >= 40));
  s += fmt::format("| peak memory of a EuRoC run < 200 MB | {} | {} |\n", figure(rss, 0, " MB"),
                   met(rss, rss < 200));
  return s;
}

}  // namespace

std::string benchMarkdown(const BenchReport& r) {
  return iterationMarkdown(r) + variantBenchMarkdown(r.variants, r.isa) + ceresMarkdown(r) +
         margEventMarkdown(r) + isaMarkdown(r) +
         "Flops counted analytically: per block m × (n_p + 4), Σ_k=0..2 2(m−k) + 4(m−k)(n_p + 3 − "
         "k).\n\n" +
         wholeRunsMarkdown(r) + targetsMarkdown(r);
}

std::string benchJson(const BenchReport& r) {
  const IterationTimes all = iterationSum(r.windows);
  Json j;
  j["speedup_ns_f32_over_sc_f64"] = figure6(r.speedup_ns_f32_over_sc_f64);
  j["speedup_over_ceres_dense_schur"] = figure6(r.speedup_over_ceres_dense_schur);
  j["speedup_over_ceres_sparse_schur"] = figure6(r.speedup_over_ceres_sparse_schur);
  j["speedup_over_ceres_best"] = figure6(r.speedup_over_ceres_best);
  j["ceres_best_solver"] = r.ceres_best_solver;
  j["qr_kernel_peak_fraction"] = figure6(r.qr_kernel_peak_fraction);
  j["qr_kernel_gflops_f32"] = figure6(r.qr_gflops_f32);
  j["qr_kernel_gflops_f64"] = figure6(r.qr_gflops_f64);
  j["peak_gflops_f32"] = figure6(r.peak_f32);
  j["peak_gflops_f64"] = figure6(r.peak_f64);
  j["peak_isa"] = r.peak_isa;
  j["realtime_factor_euroc_mh01"] =
      figure6(wholeRunField(r, "euroc/MH_01_easy", "ns-qr-sqrt-f32", &WholeRun::realtime_factor));
  j["realtime_factor_kitti00"] =
      figure6(wholeRunField(r, "kitti/00", "ns-qr-sqrt-f32", &WholeRun::realtime_factor));
  j["whole_run_opt_ratio_sc_f64_over_ns_f32_euroc_mh01"] = figure6(wholeRunOptRatio(r));
  j["peak_rss_mb_euroc_mh01"] =
      figure6(wholeRunField(r, "euroc/MH_01_easy", "ns-qr-sqrt-f32", &WholeRun::peak_rss_mb));
  j["run_frames"] = r.run_frames;
  j["run_frames_note"] = runFramesNote(r);
  j["lm_iteration_us_ns_f32"] = figure6(all.ns.f32 * 1e6);
  j["lm_iteration_us_sc_f64"] = figure6(all.sc.f64 * 1e6);
  j["lm_iteration_us_ns_f64"] = figure6(all.ns.f64 * 1e6);
  j["lm_iteration_us_ns_mixed"] = figure6(sum(r.windows, &WindowTimes::ns_mixed) * 1e6);
  j["windows"] = r.windows.size();
  j["rounds"] = r.rounds;
  j["load_before"] = r.load_before;
  j["load_after"] = r.load_after;
  j["git"] = r.git_sha;
  j["date"] = r.date_utc;
  j["isa"] = r.isa;
  j["per_isa"] = isaJson(r);
  j["variants"] = variantBenchJson(r.variants);
  return j.dump(2);
}

Variant IterationCell::variant() const {
  Variant v;
  v.opt = elimination;
  v.marg = elimination == OptElimination::kNullspace ? MargMethod::kQr : MargMethod::kSchur;
  v.storage.representation =
      elimination == OptElimination::kNullspace ? Representation::kSqrt : Representation::kHessian;
  v.precision = precision;
  return v;
}

}  // namespace marglab
