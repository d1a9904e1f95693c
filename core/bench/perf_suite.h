#pragma once
// Measurements shared by the Google Benchmark suite (bench/) and `marglab bench`:
//   - the shipped captured windows (datasets/windows/),
//   - a single-core floating-point peak: independent FMA chains in registers (AVX-512F or
//     AVX2+FMA where the CPU has them, chosen at run time), and the peak of each instruction set
//     the kernels are compiled for (core/linalg/isa.h; SSE2: multiply + add, no FMA),
//   - timing of several candidates side by side: rounds in which every candidate runs one batch,
//     the best batch per candidate kept (external load only ever adds time).

#include <functional>
#include <string>
#include <vector>

#include "core/estimator/estimator.h"
#include "core/linalg/isa.h"

namespace marglab {

struct NamedWindow {
  std::string name;  // file name without .win.gz
  WindowSnapshot window;
};

// Every *.win.gz under `dir` (default: <datasets>/windows), sorted by name.
std::vector<NamedWindow> loadWindows(const std::string& dir = "");

struct FmaPeak {
  double gflops = 0;
  std::string isa;  // "avx512f", "avx2+fma", "sse2 mul+add"
};
// Single-core peak in GFLOP/s for float or double, over about `seconds`.
FmaPeak machinePeak(bool single_precision, double seconds = 0.2);
// The peak of one ISA (the CPU must support it).
FmaPeak isaPeak(Isa isa, bool single_precision, double seconds = 0.2);

// Seconds per call of each candidate: `rounds` rounds, each running every candidate for a batch of
// at least `batch_s` seconds in turn; the best batch average per candidate.
std::vector<double> timeSideBySide(const std::vector<std::function<void()>>& candidates, int rounds,
                                   double batch_s);

// Peak resident set size of this process (VmHWM) and of finished children (getrusage), in MB.
double peakRssSelfMb();
double peakRssChildrenMb();

}  // namespace marglab
