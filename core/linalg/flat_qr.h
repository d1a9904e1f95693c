#pragma once
// Flat rank-revealing Householder QR and square-root marginalization
// (Demmel et al., "Square Root Marginalization for Sliding-Window Bundle Adjustment", ICCV 2021,
// §4.2 and Fig. 3).
//
// Input is the stacked square-root system A = [J_μ | J_κ | r] with N rows: the n_μ columns to
// marginalize first, then the n_κ columns to keep, then the residual. Householder reflections are
// applied column by column without pivoting, with a row pointer i (the next pivot row). For
// column k let β = ‖A(i:N, k)‖:
//   β > τ_k : reflect rows i..N so that A(i,k) = ±β and A(i+1:N,k) = 0, apply the reflection to
//             every column right of k (including r), then i ← i + 1;
//   β ≤ τ_k : column k is numerically in the span of the previous columns; write zeros into
//             A(i:N,k) and keep i. Standard Householder QR would consume a row here and leave a
//             step of two rows in R; the flat QR never rises by more than one row (Fig. 3, right).
// After the first n_μ columns i = r_μ = rank(J_μ); after all columns i = r = rank(J). Then
//
//          ⎡ R_1μ  R_1κ  r'_1 ⎤  rows 0 .. r_μ
//   QᵀA =  ⎢  0    R_2κ  r'_2 ⎥  rows r_μ .. r
//          ⎣  0     0    r'_3 ⎦  rows r .. N   (constant part of the energy, dropped)
//
// and the prior is J_m = R̃ = R_2κ, r_m = r̃ = r'_2, for which (eqs. 19–25)
//   R̃ᵀR̃ = H_κκ − H_κμ H_μμ⁺ H_μκ,   R̃ᵀr̃ = b_κ − H_κμ H_μμ⁺ b_μ,
// the pseudo-Schur complement, without forming H. R̃ has rank(H̃) = r − r_μ rows (at least one row
// is returned, zero if the prior is empty, so that its storage never degenerates).
//
// Threshold τ_k (recorded in the result):
//   kAbsolute: τ_k = τ, default √ε of the scalar type (3.45e-4 f32, 1.49e-8 f64) — the reference
//              implementation's choice; meaningful when the columns are O(1) (whitened residuals).
//   kRelative: τ_k = τ · ‖A(:,k)‖ of the input column, default τ = √ε: a column counts as dependent
//              when less than √ε of its norm lies outside the span of the previous columns; scale
//              invariant per variable. A zero input column is always dependent.

#include <string>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/common/enum_names.h"
#include "core/common/scalar.h"
#include "core/common/status.h"

namespace marglab {

enum class RankThresholdMode { kAbsolute, kRelative };
inline constexpr EnumNames<RankThresholdMode, 2> kRankThresholdModeNames{
    {{RankThresholdMode::kAbsolute, "absolute"}, {RankThresholdMode::kRelative, "relative"}}};
inline const char* toString(RankThresholdMode value) {
  return nameOf(kRankThresholdModeNames, value);
}
inline bool parseRankThresholdMode(const std::string& text, RankThresholdMode* value) {
  return parseName(kRankThresholdModeNames, text, value);
}

template <typename Scalar>
struct FlatQrOptions {
  RankThresholdMode mode = RankThresholdMode::kAbsolute;
  Scalar threshold = NumericTraits<Scalar>::sqrtEpsilon();
};

struct FlatQrInfo {
  int rank_prefix = 0;         // rank of the first n_prefix columns (r_μ)
  int rank = 0;                // rank of all n_cols columns (r)
  std::vector<int> pivot_row;  // per column: its pivot row, or -1 if dependent
};

// Square-root prior E_m(x) = ½‖r_m + J_m (x − x⁰)‖² (paper eq. 4).
template <typename Scalar>
struct SqrtPrior {
  MatX<Scalar> J;
  VecX<Scalar> r;
};

template <typename Scalar>
struct FlatQrMarginalization {
  SqrtPrior<Scalar> prior;  // J_m = R̃ (rank − marg_rank rows, ≥ 1), r_m = r̃
  int marg_rank = 0;        // r_μ
  int total_rank = 0;       // r
  RankThresholdMode mode = RankThresholdMode::kAbsolute;
  Scalar threshold = 0;
  Status status;
};

// Flat QR in place on A (N × (n_cols + n_extra)): the first n_cols columns are factorized, the
// reflections are applied to the extra columns (right-hand sides) too. Entries below the
// staircase are written as exact zeros.
template <typename Scalar>
FlatQrInfo flatQrInPlace(Eigen::Ref<MatX<Scalar>> A, int n_cols, int n_prefix,
                         const FlatQrOptions<Scalar>& options);

// Marginalizes the first n_marg columns of A = [J_μ | J_κ | r] (consumed).
template <typename Scalar>
FlatQrMarginalization<Scalar> flatQrMarginalize(MatX<Scalar> A, int n_marg,
                                                const FlatQrOptions<Scalar>& options = {});

}  // namespace marglab
