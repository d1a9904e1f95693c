#pragma once
// The instruction set the hot kernels run with (docs/design.md §ISA dispatch). The landmark
// elimination, the reduced-system accumulation and its damped solve are compiled three times —
// baseline x86-64 (SSE2), AVX2 + FMA and AVX-512 (F, DQ, VL, BW) — each copy isolated in its own
// partially linked object (core/estimator/linearization_kernels.h), and one is chosen per process:
// the best the CPU supports unless `--isa` forces one. The same ISA gives the same numbers bit for
// bit; the ISAs differ in the last bits (FMA contraction, vector width changes the order of sums).

#include <cstddef>
#include <string>
#include <vector>

namespace marglab {

enum class Isa { kSse2, kAvx2, kAvx512 };

inline constexpr Isa kAllIsas[] = {Isa::kSse2, Isa::kAvx2, Isa::kAvx512};

// "sse2" | "avx2" | "avx512" (the results file's isa attribute and the bench's isa key).
const char* isaName(Isa isa);
// Whether this CPU can run the ISA's kernels.
bool cpuSupports(Isa isa);
// Whether this build has the ISA's kernels: every ISA, except in a sanitizer build (SSE2 only,
// core/isa_kernels.cmake says why).
bool isaBuilt(Isa isa);
// Built and supported by this CPU: the ISAs a run can use.
inline bool isaAvailable(Isa isa) { return isaBuilt(isa) && cpuSupports(isa); }
// The available ISAs, narrowest first.
std::vector<Isa> availableIsas();
// The widest available ISA.
Isa bestIsa();

// The process-wide ISA: bestIsa() until set. Set it once at start-up, before any estimator object
// is built: a linearization keeps the ISA it was made with. `how` says how it was chosen (the
// results file's isa_choice; `--isa auto` measures, core/bench/isa_choice.h).
Isa activeIsa();
void setActiveIsa(Isa isa);
void setActiveIsa(Isa isa, const std::string& how);
// How the active ISA was chosen: "widest available" until set with a reason.
std::string activeIsaChoice();
// "auto" | "sse2" | "avx2" | "avx512" → the ISA to run ("auto": the widest; the CLI's `--isa auto`
// measures instead, core/bench/isa_choice.h); UsageError for another name, InputError (exit 1)
// when the ISA asked for is not available (the CPU lacks it, or the build does).
Isa resolveIsa(const std::string& name);

}  // namespace marglab

// malloc and calloc of the ISA copies (core/isa_kernels.cmake renames their calls to these):
// 64-byte-aligned blocks that free() releases, as Eigen's AVX / AVX-512 code expects of its
// buffers. calloc matters as much as malloc: GCC turns an inlined Eigen allocation followed by
// setZero (a product's result) into one calloc call, and Eigen's vectorized loops that peel to the
// first aligned coefficient (the selfadjoint matrix-vector product) would otherwise group their
// sums by the heap's layout.
extern "C" void* marglab_isa_aligned_malloc(std::size_t size);
extern "C" void* marglab_isa_aligned_calloc(std::size_t count, std::size_t size);
