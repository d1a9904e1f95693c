// Prototype for issue #21 ("batched landmark kernels: structure-of-arrays across landmarks, or
// fixed-size kernels, whichever the measurements favour"): a structure-of-arrays Householder QR of
// the landmark blocks, one AVX-512 lane = one landmark (16 f32 lanes), against the estimator's
// row-major kernel (LandmarkBlockNs<float>::setFromJacobians with the avx512 kernels), on the
// landmark blocks of the four shipped bench windows. Landmarks are grouped by pose-block count,
// batched 16 at a time, rows zero-padded to the batch's tallest; the SoA path gathers [J_p J_l r]
// from the linearization's column-major Jacobians and scatters the result back to the row-major
// blocks the reduced-system accumulation and back-substitution read. Not part of the build: the
// result (results/perf/issue21_kernels.md, "Batched landmark kernels") is why.
//
// Build and run from a configured release build folder (two translation units: the kernel is
// compiled for AVX-512 and isolated, as core/isa_kernels.cmake isolates the estimator's kernels):
//   sed -n '/^\/\/ ---- kernel/,/^\/\/ ---- driver/p' soa_landmark_qr.cpp > /tmp/soa_kernel.cpp
//   sed -n '/^\/\/ ---- driver/,$p' soa_landmark_qr.cpp > /tmp/soa_main.cpp
//   g++ -c -O3 -DNDEBUG -mavx512f -mavx512dq -mavx512vl -mavx512bw -mavx2 -mfma -ffp-contract=fast \
//     -DEIGEN_MAX_ALIGN_BYTES=16 -fvisibility=hidden -fvisibility-inlines-hidden -std=c++17 \
//     -isystem /usr/include/eigen3 /tmp/soa_kernel.cpp -o /tmp/k.o
//   ld -r /tmp/k.o -o /tmp/soa_k.o && objcopy --keep-global-symbol=_Z14soaHouseholderPfiiiS_S_ /tmp/soa_k.o
//   then compile /tmp/soa_main.cpp with the flags and link line of marglab_cli (build/tools/
//   CMakeFiles/marglab_cli.dir/{flags.make,link.txt}) plus /tmp/soa_k.o; run: ./soa 2000

// ---- kernel
#include <Eigen/Dense>
#include <limits>
constexpr int L = 16;  // f32 lanes of a zmm
using Lane = Eigen::Array<float, L, 1>;
using LaneMap = Eigen::Map<Lane>;

// A: [(i*n + j)*L + l], rows m (padded), n = n_p + 4.
__attribute__((visibility("hidden"))) void soaHouseholderImpl(float* A, int m, int n, int n_p, float* v, float* w) {
  for (int k = 0; k < 3; ++k) {
    const int col = n_p + k;
    auto at = [&](int i, int j) { return LaneMap(A + (size_t(i) * n + j) * L); };
    const Lane c0 = at(k, col);
    Lane tail = Lane::Zero();
    for (int i = k + 1; i < m; ++i) tail += at(i, col) * at(i, col);
    const auto active = tail > std::numeric_limits<float>::min();
    Lane beta = (c0 * c0 + tail).sqrt();
    beta = (c0 >= 0).select(-beta, beta);
    const Lane denom = c0 - beta;
    for (int i = k + 1; i < m; ++i) LaneMap(v + i * L) = active.select(at(i, col) / denom, Lane::Zero());
    const Lane tau = active.select((beta - c0) / beta, Lane::Zero());
    for (int j = 0; j < n; ++j) {
      Lane acc = at(k, j);
      for (int i = k + 1; i < m; ++i) acc += LaneMap(v + i * L) * at(i, j);
      LaneMap(w + j * L) = acc * tau;
    }
    for (int j = 0; j < n; ++j) at(k, j) -= LaneMap(w + j * L);
    for (int i = k + 1; i < m; ++i) {
      const Lane vi = LaneMap(v + i * L);
      for (int j = 0; j < n; ++j) at(i, j) -= vi * LaneMap(w + j * L);
    }
    at(k, col) = active.select(beta, c0);
    for (int i = k + 1; i < m; ++i) at(i, col) = Lane::Zero();
  }
}


void soaHouseholder(float* A, int m, int n, int n_p, float* v, float* w) { soaHouseholderImpl(A, m, n, n_p, v, w); }

// ---- driver
// Prototype: structure-of-arrays landmark QR (one SIMD lane = one landmark) vs the row-major kernel.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <cmath>
#include <limits>
#include "core/bench/perf_suite.h"
#include "core/bench/window_kernels.h"
#include "core/estimator/linearization_kernels.h"
#include "core/estimator/variant.h"
using namespace marglab;
constexpr int L = 16;
void soaHouseholder(float* A, int m, int n, int n_p, float* v, float* w);
int main(int argc, char** argv) {
  int reps = std::atoi(argv[1]);
  auto wins = loadWindows("datasets/windows");
  std::vector<std::unique_ptr<WindowKernels<float>>> ks; std::vector<std::vector<PoseBlockMap>> maps;
  for (auto& nw : wins) {
    ks.push_back(std::make_unique<WindowKernels<float>>(nw.window, Variant::parse("ns-qr-sqrt-f32")));
    ks.back()->linearize(); maps.emplace_back();
    for (int i = 0; i < ks.back()->numLandmarkBlocks(); ++i) maps.back().push_back(ks.back()->blockMap(i));
  }
  size_t n_lm = 0; for (auto& m : maps) n_lm += m.size();
  auto qr = kernelsOf(Isa::kAvx512).f32.landmark_qr;
  auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < reps; ++r) for (size_t w = 0; w < ks.size(); ++w) qr(ks[w]->landmarkJacobians(), maps[w]);
  double s_row = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // SoA: group by n_p, batches of L, rows padded; gather from J (col-major), QR, scatter to row-major.
  std::vector<float> A, v(64 * L), w(128 * L);
  std::vector<std::vector<float>> out(4096);
  double t_gather = 0, t_qr = 0, t_scatter = 0; size_t lanes_used = 0, batches = 0;
  for (int r = 0; r < reps; ++r) for (size_t wi = 0; wi < ks.size(); ++wi) {
    const auto& lins = ks[wi]->landmarkJacobians();
    std::map<int, std::vector<int>> groups;
    for (int l = 0; l < (int)lins.size(); ++l) groups[lins[l].J_p.cols()].push_back(l);
    for (auto& [n_p, members] : groups) {
      const int n = n_p + 4;
      for (size_t b0 = 0; b0 < members.size(); b0 += L) {
        const int cnt = std::min<int>(L, members.size() - b0);
        int m = 0; for (int q = 0; q < cnt; ++q) m = std::max<int>(m, lins[members[b0 + q]].J_l.rows());
        auto g0 = std::chrono::steady_clock::now();
        A.assign(size_t(m) * n * L, 0.f);
        for (int q = 0; q < cnt; ++q) {
          const auto& lin = lins[members[b0 + q]];
          const int mq = lin.J_l.rows();
          for (int j = 0; j < n_p; ++j) for (int i = 0; i < mq; ++i) A[(size_t(i) * n + j) * L + q] = lin.J_p(i, j);
          for (int j = 0; j < 3; ++j) for (int i = 0; i < mq; ++i) A[(size_t(i) * n + n_p + j) * L + q] = lin.J_l(i, j);
          for (int i = 0; i < mq; ++i) A[(size_t(i) * n + n_p + 3) * L + q] = lin.r[i];
        }
        auto g1 = std::chrono::steady_clock::now();
        soaHouseholder(A.data(), m, n, n_p, v.data(), w.data());
        auto g2 = std::chrono::steady_clock::now();
        for (int q = 0; q < cnt; ++q) {
          const int mq = lins[members[b0 + q]].J_l.rows();
          auto& o = out[members[b0 + q]]; o.resize(size_t(mq + 3) * n);
          for (int i = 0; i < mq; ++i) for (int j = 0; j < n; ++j) o[size_t(i) * n + j] = A[(size_t(i) * n + j) * L + q];
        }
        auto g3 = std::chrono::steady_clock::now();
        t_gather += std::chrono::duration<double>(g1 - g0).count();
        t_qr += std::chrono::duration<double>(g2 - g1).count();
        t_scatter += std::chrono::duration<double>(g3 - g2).count();
        lanes_used += cnt; ++batches;
      }
    }
  }
  const double N = double(n_lm) * reps;
  std::printf("row-major setFromJacobians (avx512 kernels): %.0f ns/landmark\n", s_row / N * 1e9);
  std::printf("SoA (%d lanes, %.0f %% filled): gather %.0f + QR %.0f + scatter %.0f = %.0f ns/landmark\n", L,
              100.0 * lanes_used / (batches * L), t_gather / N * 1e9, t_qr / N * 1e9, t_scatter / N * 1e9,
              (t_gather + t_qr + t_scatter) / N * 1e9);
}
