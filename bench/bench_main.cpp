// The benchmark suite of issue #8 on the shipped captured windows (datasets/windows/):
//   LmPhase/<phase>/<variant>/<window>  one LM iteration's phases — linearize, eliminate the
//       landmarks, form + solve the reduced camera system — their sum (iteration), and the
//       estimator's optimizer limited to one iteration (with its cost evaluations);
//       variants ns-qr-sqrt (√BA, nullspace projection) and sc-sc-sq (Schur baseline) × f32/f64;
//   Marginalize/<qr|sc>/<f32|f64>/<window>  one marginalization event (oldest keyframe with its
//       landmarks, VIO: and the oldest state's speed-bias) by the flat QR or the Schur complement;
//   QrKernel/<f32|f64>/<window>  the landmark-block Householder QR (LandmarkBlockNs::
//       setFromJacobians) over all landmarks of the window, GFLOP/s from the analytic flop count;
//   FmaPeak/<f32|f64>  the single-core peak (FMA chains in registers) of this machine.

#include <benchmark/benchmark.h>
#include <fmt/core.h>

#include "core/bench/perf_suite.h"
#include "core/bench/window_kernels.h"
#include "core/linalg/landmark_block.h"

namespace marglab {
namespace {

const std::vector<NamedWindow>& windows() {
  static const std::vector<NamedWindow> w = loadWindows();
  return w;
}

template <typename Scalar>
void lmPhase(benchmark::State& state, const WindowSnapshot& w, const Variant& v,
             const std::string& phase) {
  WindowKernels<Scalar> k(w, v);
  k.linearize();
  if (!k.eliminate().ok()) state.SkipWithError("elimination failed");
  for (auto _ : state) {
    Status s = Status::Ok();
    if (phase == "linearize") {
      k.linearize();
    } else if (phase == "eliminate") {
      s = k.eliminate();
    } else if (phase == "solve") {
      s = k.solve();
    } else if (phase == "iteration") {
      s = k.iteration();
    } else {
      s = k.optimizeOnce();
    }
    if (!s.ok()) state.SkipWithError(s.toString().c_str());
    benchmark::ClobberMemory();
  }
  state.counters["landmarks"] = k.numLandmarkBlocks();
}

template <typename Scalar>
void marginalize(benchmark::State& state, const WindowSnapshot& w, const Variant& v) {
  WindowKernels<Scalar> k(w, v);
  for (auto _ : state) {
    Status s = k.marginalize(v.marg);
    if (!s.ok()) state.SkipWithError(s.toString().c_str());
  }
}

template <typename Scalar>
void qrKernel(benchmark::State& state, const WindowSnapshot& w) {
  Variant v = Variant::parse("ns-qr-sqrt-f64");
  WindowKernels<Scalar> k(w, v);
  k.linearize();
  const int L = k.numLandmarkBlocks();
  std::vector<PoseBlockMap> maps;
  double flops = 0;
  for (int i = 0; i < L; ++i) {
    maps.push_back(k.blockMap(i));
    flops += landmarkQrFlops(static_cast<int>(k.blockJp(i).rows()),
                             static_cast<int>(k.blockJp(i).cols()) + 4);
  }
  LandmarkBlockNs<Scalar> block;
  for (auto _ : state) {
    for (int i = 0; i < L; ++i) {
      Status s = block.setFromJacobians(k.blockJp(i), k.blockJl(i), k.blockR(i), maps[i]);
      benchmark::DoNotOptimize(s);
    }
  }
  state.counters["GFLOPS"] =
      benchmark::Counter(flops * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["blocks"] = L;
}

void fmaPeak(benchmark::State& state, bool sp) {
  FmaPeak peak;
  for (auto _ : state) peak = machinePeak(sp, 0.1);
  state.counters["GFLOPS"] = peak.gflops;
  state.SetLabel(fmt::format("{} {:.2f} GFLOP/s", peak.isa, peak.gflops));
}

}  // namespace
}  // namespace marglab

int main(int argc, char** argv) {
  using namespace marglab;
  for (const NamedWindow& nw : windows()) {
    for (const char* method : {"ns-qr-sqrt", "sc-sc-sq"}) {
      for (const char* prec : {"f32", "f64"}) {
        const Variant v = Variant::parse(fmt::format("{}-{}", method, prec));
        for (const char* phase : {"linearize", "eliminate", "solve", "iteration", "optimize1"}) {
          const std::string name = fmt::format("LmPhase/{}/{}/{}", phase, v.name(), nw.name);
          const WindowSnapshot* w = &nw.window;
          const std::string ph = phase;
          benchmark::RegisterBenchmark(name.c_str(), [w, v, ph](benchmark::State& st) {
            if (v.precision == Precision::kF32) {
              lmPhase<float>(st, *w, v, ph);
            } else {
              lmPhase<double>(st, *w, v, ph);
            }
          })->Unit(benchmark::kMicrosecond);
        }
      }
    }
    for (const char* method : {"ns-qr-sqrt", "ns-sc-sqrt"}) {
      for (const char* prec : {"f32", "f64"}) {
        const Variant v = Variant::parse(fmt::format("{}-{}", method, prec));
        const std::string name = fmt::format(
            "Marginalize/{}/{}/{}", v.marg == MargMethod::kQr ? "qr" : "sc", prec, nw.name);
        const WindowSnapshot* w = &nw.window;
        benchmark::RegisterBenchmark(name.c_str(), [w, v](benchmark::State& st) {
          if (v.precision == Precision::kF32) {
            marginalize<float>(st, *w, v);
          } else {
            marginalize<double>(st, *w, v);
          }
        })->Unit(benchmark::kMicrosecond);
      }
    }
    const WindowSnapshot* w = &nw.window;
    benchmark::RegisterBenchmark(fmt::format("QrKernel/f32/{}", nw.name).c_str(),
                                 [w](benchmark::State& st) { qrKernel<float>(st, *w); })
        ->Unit(benchmark::kMicrosecond);
    benchmark::RegisterBenchmark(fmt::format("QrKernel/f64/{}", nw.name).c_str(),
                                 [w](benchmark::State& st) { qrKernel<double>(st, *w); })
        ->Unit(benchmark::kMicrosecond);
  }
  benchmark::RegisterBenchmark("FmaPeak/f32", [](benchmark::State& st) {
    fmaPeak(st, true);
  })->Iterations(1);
  benchmark::RegisterBenchmark("FmaPeak/f64", [](benchmark::State& st) {
    fmaPeak(st, false);
  })->Iterations(1);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
