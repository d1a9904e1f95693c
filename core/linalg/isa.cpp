#include "core/linalg/isa.h"

#include <fmt/core.h>

#include <atomic>
#include <cstdlib>
#include <cstring>
#include <limits>

#include "core/common/error.h"

namespace marglab {
namespace {

std::atomic<int> g_active{-1};  // −1: not set, bestIsa()
std::string& activeChoice() {   // set once at start-up, with the ISA
  static std::string how = "widest available";
  return how;
}

}  // namespace

const char* isaName(Isa isa) {
  switch (isa) {
    case Isa::kAvx512:
      return "avx512";
    case Isa::kAvx2:
      return "avx2";
    case Isa::kSse2:
      break;
  }
  return "sse2";
}

bool cpuSupports(Isa isa) {
  __builtin_cpu_init();
  switch (isa) {
    case Isa::kAvx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
             __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512bw") &&
             cpuSupports(Isa::kAvx2);
    case Isa::kAvx2:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    case Isa::kSse2:
      break;
  }
  return true;  // the x86-64 baseline
}

bool isaBuilt(Isa isa) {
#ifdef MARGLAB_ISA_SSE2_ONLY
  return isa == Isa::kSse2;
#else
  (void)isa;
  return true;
#endif
}

std::vector<Isa> availableIsas() {
  std::vector<Isa> out;
  for (const Isa isa : kAllIsas) {
    if (isaAvailable(isa)) out.push_back(isa);
  }
  return out;
}

Isa bestIsa() {
  if (isaAvailable(Isa::kAvx512)) return Isa::kAvx512;
  if (isaAvailable(Isa::kAvx2)) return Isa::kAvx2;
  return Isa::kSse2;
}

Isa activeIsa() {
  const int isa = g_active.load(std::memory_order_relaxed);
  return isa < 0 ? bestIsa() : static_cast<Isa>(isa);
}

void setActiveIsa(Isa isa) { g_active.store(static_cast<int>(isa), std::memory_order_relaxed); }

void setActiveIsa(Isa isa, const std::string& how) {
  setActiveIsa(isa);
  activeChoice() = how;
}

std::string activeIsaChoice() { return activeChoice(); }

Isa resolveIsa(const std::string& name) {
  if (name == "auto") return bestIsa();
  for (const Isa isa : kAllIsas) {
    if (name != isaName(isa)) continue;
    if (!cpuSupports(isa)) {
      throw InputError("--isa", 0, fmt::format("this CPU does not support {}", name));
    }
    if (!isaBuilt(isa)) {
      throw InputError("--isa", 0,
                       fmt::format("this build has only the sse2 kernels (a sanitizer build), "
                                   "not {}",
                                   name));
    }
    return isa;
  }
  throw UsageError(fmt::format("--isa {}: expected auto, sse2, avx2 or avx512", name));
}

}  // namespace marglab

extern "C" void* marglab_isa_aligned_malloc(std::size_t size) {
  void* p = nullptr;
  return posix_memalign(&p, 64, size) == 0 ? p : nullptr;
}

extern "C" void* marglab_isa_aligned_calloc(std::size_t count, std::size_t size) {
  if (size != 0 && count > std::numeric_limits<std::size_t>::max() / size) return nullptr;
  void* p = marglab_isa_aligned_malloc(count * size);
  if (p != nullptr) std::memset(p, 0, count * size);
  return p;
}
