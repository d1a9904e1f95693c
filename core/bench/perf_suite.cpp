#include "core/bench/perf_suite.h"

#include <sys/resource.h>

#include <immintrin.h>
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>

#include "core/data/sequence.h"
#include "core/estimator/window_io.h"

namespace marglab {
namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// 12 independent accumulators hide the FMA latency (4 cycles) on two FMA ports.
constexpr int kChains = 12;
// The kernels store their result here: a volatile store is a side effect, which keeps the compiler
// from moving a kernel's pure arithmetic across the clock reads that time it.
volatile double g_sink = 0;

__attribute__((target("avx512f"))) __attribute__((noinline)) double fmaAvx512(long iters, bool sp) {
  if (sp) {
    __m512 acc[kChains];
    const __m512 a = _mm512_set1_ps(0.999999f), b = _mm512_set1_ps(1e-7f);
    for (int c = 0; c < kChains; ++c) acc[c] = _mm512_set1_ps(static_cast<float>(c));
    for (long i = 0; i < iters; ++i) {
      for (int c = 0; c < kChains; ++c) acc[c] = _mm512_fmadd_ps(acc[c], a, b);
    }
    alignas(64) float out[16];
    float sum = 0;
    for (int c = 0; c < kChains; ++c) {
      _mm512_store_ps(out, acc[c]);
      for (float v : out) sum += v;
    }
    g_sink = sum;
    return sum;
  }
  __m512d acc[kChains];
  const __m512d a = _mm512_set1_pd(0.999999), b = _mm512_set1_pd(1e-7);
  for (int c = 0; c < kChains; ++c) acc[c] = _mm512_set1_pd(c);
  for (long i = 0; i < iters; ++i) {
    for (int c = 0; c < kChains; ++c) acc[c] = _mm512_fmadd_pd(acc[c], a, b);
  }
  alignas(64) double out[8];
  double sum = 0;
  for (int c = 0; c < kChains; ++c) {
    _mm512_store_pd(out, acc[c]);
    for (double v : out) sum += v;
  }
  g_sink = sum;
  return sum;
}

__attribute__((target("avx2,fma"))) __attribute__((noinline)) double fmaAvx2(long iters, bool sp) {
  if (sp) {
    __m256 acc[kChains];
    const __m256 a = _mm256_set1_ps(0.999999f), b = _mm256_set1_ps(1e-7f);
    for (int c = 0; c < kChains; ++c) acc[c] = _mm256_set1_ps(static_cast<float>(c));
    for (long i = 0; i < iters; ++i) {
      for (int c = 0; c < kChains; ++c) acc[c] = _mm256_fmadd_ps(acc[c], a, b);
    }
    alignas(32) float out[8];
    float sum = 0;
    for (int c = 0; c < kChains; ++c) {
      _mm256_store_ps(out, acc[c]);
      for (float v : out) sum += v;
    }
    g_sink = sum;
    return sum;
  }
  __m256d acc[kChains];
  const __m256d a = _mm256_set1_pd(0.999999), b = _mm256_set1_pd(1e-7);
  for (int c = 0; c < kChains; ++c) acc[c] = _mm256_set1_pd(c);
  for (long i = 0; i < iters; ++i) {
    for (int c = 0; c < kChains; ++c) acc[c] = _mm256_fmadd_pd(acc[c], a, b);
  }
  alignas(32) double out[4];
  double sum = 0;
  for (int c = 0; c < kChains; ++c) {
    _mm256_store_pd(out, acc[c]);
    for (double v : out) sum += v;
  }
  g_sink = sum;
  return sum;
}

// Baseline SSE2: a multiply and an add per element (the compiler has no FMA to fuse them into).
__attribute__((noinline)) double mulAddSse2(long iters, bool sp) {
  if (sp) {
    __m128 acc[kChains];
    const __m128 a = _mm_set1_ps(0.999999f), b = _mm_set1_ps(1e-7f);
    for (int c = 0; c < kChains; ++c) acc[c] = _mm_set1_ps(static_cast<float>(c));
    for (long i = 0; i < iters; ++i) {
      for (int c = 0; c < kChains; ++c) acc[c] = _mm_add_ps(_mm_mul_ps(acc[c], a), b);
    }
    alignas(16) float out[4];
    float sum = 0;
    for (int c = 0; c < kChains; ++c) {
      _mm_store_ps(out, acc[c]);
      for (float v : out) sum += v;
    }
    g_sink = sum;
    return sum;
  }
  __m128d acc[kChains];
  const __m128d a = _mm_set1_pd(0.999999), b = _mm_set1_pd(1e-7);
  for (int c = 0; c < kChains; ++c) acc[c] = _mm_set1_pd(c);
  for (long i = 0; i < iters; ++i) {
    for (int c = 0; c < kChains; ++c) acc[c] = _mm_add_pd(_mm_mul_pd(acc[c], a), b);
  }
  alignas(16) double out[2];
  double sum = 0;
  for (int c = 0; c < kChains; ++c) {
    _mm_store_pd(out, acc[c]);
    for (double v : out) sum += v;
  }
  g_sink = sum;
  return sum;
}

// Best of repeated timed runs of `kernel(iters)`; flops per iteration given.
double peakOf(double (*kernel)(long, bool), bool sp, double flops_per_iter, double seconds) {
  volatile double sink = 0;
  long iters = 1 << 12;
  // Calibrate to ~10 ms per run.
  for (;;) {
    const auto t0 = Clock::now();
    sink = sink + kernel(iters, sp);
    if (since(t0) > 0.01 || iters > (1L << 34)) break;
    iters *= 2;
  }
  double best = 0;
  const auto start = Clock::now();
  do {
    const auto t0 = Clock::now();
    sink = sink + kernel(iters, sp);
    best = std::max(best, flops_per_iter * static_cast<double>(iters) / since(t0) * 1e-9);
  } while (since(start) < seconds);
  return best;
}

}  // namespace

std::vector<NamedWindow> loadWindows(const std::string& dir_in) {
  const std::filesystem::path dir = dir_in.empty()
                                        ? std::filesystem::path(datasetsRoot()) / "windows"
                                        : std::filesystem::path(dir_in);
  std::vector<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.size() > 7 && name.compare(name.size() - 7, 7, ".win.gz") == 0) {
      files.push_back(entry.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  std::vector<NamedWindow> out;
  for (const std::string& f : files) {
    std::string name = std::filesystem::path(f).filename().string();
    name.resize(name.size() - 7);
    out.push_back({name, readWindow(f)});
  }
  return out;
}

namespace {

// Peaks per instruction set: flops per kernel iteration = 2 (FMA or mul+add) × chains × lanes.
FmaPeak avx512Peak(bool sp, double seconds) {
  return {peakOf(fmaAvx512, sp, 2.0 * kChains * (sp ? 16 : 8), seconds), "avx512f"};
}
FmaPeak avx2Peak(bool sp, double seconds) {
  return {peakOf(fmaAvx2, sp, 2.0 * kChains * (sp ? 8 : 4), seconds), "avx2+fma"};
}
FmaPeak sse2Peak(bool sp, double seconds) {
  return {peakOf(mulAddSse2, sp, 2.0 * kChains * (sp ? 4 : 2), seconds), "sse2 mul+add"};
}

}  // namespace

FmaPeak machinePeak(bool sp, double seconds) {
  if (__builtin_cpu_supports("avx512f")) return avx512Peak(sp, seconds);
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
    return avx2Peak(sp, seconds);
  }
  return sse2Peak(sp, seconds);
}

FmaPeak isaPeak(Isa isa, bool sp, double seconds) {
  switch (isa) {
    case Isa::kAvx512:
      return avx512Peak(sp, seconds);
    case Isa::kAvx2:
      return avx2Peak(sp, seconds);
    case Isa::kSse2:
      break;
  }
  return sse2Peak(sp, seconds);
}

std::vector<double> timeSideBySide(const std::vector<std::function<void()>>& candidates, int rounds,
                                   double batch_s) {
  const size_t n = candidates.size();
  std::vector<long> batch(n, 1);
  // Calibrate each candidate's batch size.
  for (size_t i = 0; i < n; ++i) {
    for (;;) {
      const auto t0 = Clock::now();
      for (long k = 0; k < batch[i]; ++k) candidates[i]();
      const double t = since(t0);
      if (t >= batch_s || batch[i] > (1L << 30)) break;
      batch[i] = t > 0 ? std::max(batch[i] * 2, static_cast<long>(batch[i] * batch_s / t * 1.2))
                       : batch[i] * 2;
    }
  }
  std::vector<double> best(n, 1e300);
  for (int r = 0; r < rounds; ++r) {
    for (size_t i = 0; i < n; ++i) {
      const auto t0 = Clock::now();
      for (long k = 0; k < batch[i]; ++k) candidates[i]();
      best[i] = std::min(best[i], since(t0) / static_cast<double>(batch[i]));
    }
  }
  return best;
}

double peakRssSelfMb() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  return -1;
}

double peakRssChildrenMb() {
  rusage usage{};
  if (getrusage(RUSAGE_CHILDREN, &usage) != 0) return -1;
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

}  // namespace marglab
