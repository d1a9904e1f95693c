#pragma once
// Scalar types the numerics are instantiated for, and the one place that fixes the numerical
// thresholds of each scalar type. Every rank decision, pseudo-inverse cut-off and clamp in the
// library reads its default from NumericTraits<Scalar>; a run records which values it used.

#include <cmath>
#include <limits>
#include <string_view>

namespace marglab {

// Explicit instantiation helper: MARGLAB_INSTANTIATE(X) expands X(float) and X(double) for the
// scalar types enabled at configure time (CMake options MARGLAB_FLOAT / MARGLAB_DOUBLE).
#if defined(MARGLAB_WITH_FLOAT)
#define MARGLAB_INSTANTIATE_FLOAT(X) X(float)
#else
#define MARGLAB_INSTANTIATE_FLOAT(X)
#endif
#define MARGLAB_INSTANTIATE(X) \
  MARGLAB_INSTANTIATE_FLOAT(X) \
  X(double)

template <typename Scalar>
struct NumericTraits {
  static constexpr Scalar kEpsilon = std::numeric_limits<Scalar>::epsilon();
  // Reference flat-QR threshold of the paper's implementation (Basalt/rootba): absolute √ε,
  // i.e. 3.45e-4 for float and 1.49e-8 for double.
  static Scalar sqrtEpsilon() { return std::sqrt(kEpsilon); }
  // Relative rank threshold for SVD / eigen based pseudo-inverses: σ ≤ tol · σ_max counts as 0.
  // n·ε is the usual numerical-rank rule (Golub & Van Loan §5.4.1) with n the matrix size.
  static Scalar pinvRelativeTolerance(int n) { return static_cast<Scalar>(n) * kEpsilon; }
  // Relative pivot floor of the gauge-exact psd projection (psd axis `g`, docs/design.md §2): an
  // LDLT pivot D_i < tol · max D of an n×n prior is rounding, not information, and is set to 0.
  // The same n·ε rule: the pivots of a nullspace direction come out of the elimination at the
  // size of its rounding, about n·ε·max D, however they fall around zero.
  static Scalar ldltPivotRelativeTolerance(int n) { return static_cast<Scalar>(n) * kEpsilon; }
  static constexpr std::string_view name() {
    if constexpr (std::is_same_v<Scalar, float>) {
      return "f32";
    } else {
      return "f64";
    }
  }
};

}  // namespace marglab
