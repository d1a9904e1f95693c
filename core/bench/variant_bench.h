#pragma once
// `marglab bench --variant V …`: one LM iteration and one marginalization event of variants the
// user names, on the captured windows, timed side by side (timeSideBySide) with the paper's √-f32
// variant ns-qr-sqrt-f32, the reference of every ratio. Made for claims about speed that depend on
// the storage, e.g. PC-SRIF's that a preconditioned Cholesky in f32 is faster than QR
// (sc-sc-sqp-f32, sc-sc-sqrtp-f32 against ns-qr-sqrt-f32). A variant whose iteration or
// marginalization fails on a window (a factorization that is not positive definite in f32) is
// recorded there as failed, with the reason, and not timed: a failure is a result, not a crash.

#include <string>
#include <vector>

#include "core/common/json.h"
#include "core/estimator/estimator.h"
#include "core/estimator/variant.h"

namespace marglab {

// The reference every chosen variant is timed beside.
inline constexpr const char* kBenchReferenceVariant = "ns-qr-sqrt-f32";

struct VariantWindowTimes {
  std::string variant;
  std::string failure;           // empty when both kernels ran
  double iteration_s = 0;        // linearize + eliminate + solve
  double marginalization_s = 0;  // one event with the variant's method and storage
};

// The chosen variants on every window, each window's entry led by the reference.
struct VariantBench {
  std::vector<std::string> windows;
  std::vector<std::vector<VariantWindowTimes>> times;  // [window][reference, variants…]
};

// The reference first, then `variants` in order (the reference itself, if named, is not repeated).
std::vector<VariantWindowTimes> timeVariants(const WindowSnapshot& window,
                                             const std::vector<Variant>& variants, int rounds,
                                             double batch_s);

// Per window and over all windows (a variant that failed on a window has no total); empty when no
// variant was named.
std::string variantBenchMarkdown(const VariantBench& bench, const std::string& isa);
Json variantBenchJson(const VariantBench& bench);

}  // namespace marglab
