#pragma once
// Schur-complement marginalization on the Hessian, with a pseudo-inverse
// (Demmel et al., ICCV 2021, eqs. 14–15 and their generalization 22–23).
//
// With H = JᵀJ and b = Jᵀr partitioned as [μ | κ] (marginalized variables first),
//   H̃ = H_κκ − H_κμ H_μμ⁺ H_μκ,        b̃ = b_κ − H_κμ H_μμ⁺ b_μ,
// and the constant the minimization over μ adds to the energy, c̃ = −½ b_μᵀ H_μμ⁺ b_μ.
// H_μμ⁺ is the Moore–Penrose pseudo-inverse from the self-adjoint eigendecomposition
// H_μμ = V Λ Vᵀ:  H_μμ⁺ = V Λ⁺ Vᵀ with λ⁺ = 1/λ for |λ| > τ and 0 otherwise.
// Negative eigenvalues beyond the threshold are inverted as they are, which is what the
// Moore–Penrose inverse of a symmetric indefinite matrix is: a Hessian that rounding made
// indefinite (single precision, paper §5.2) is not repaired here, so its effect is measured.
//
// Threshold τ (recorded in the result):
//   kRelative (default): τ = t · max|λ|, default t = n_μ · ε (the numerical-rank rule of
//             Golub & Van Loan §5.4.1 applied to H_μμ);
//   kAbsolute: τ = t.
//
// Also: conversion of a Hessian prior (H, b) to square-root form by LDLT (paper §4.3.1 and its
// ablation `sc` marginalization + `sqrt` storage): H = Pᵀ L D Lᵀ P  ⇒  J = √D Lᵀ P, and
// r = √D⁺ L⁻¹ P b so that Jᵀr = b whenever b ∈ range(H). Negative pivots D_i (rounding on a
// semi-definite H) are clamped to 0 and counted; with a relative floor t > 0 so is every pivot
// D_i < t · max D, which makes a nullspace that rounding left with small positive pivots exact
// again: J's nullspace is then spanned by the directions Pᵀ L⁻ᵀ e_i of the clamped pivots.

#include "core/common/eigen_types.h"
#include "core/common/scalar.h"
#include "core/common/status.h"
#include "core/linalg/flat_qr.h"

namespace marglab {

// Hessian prior E_m(x) = ½ (x − x⁰)ᵀ H (x − x⁰) + bᵀ (x − x⁰) + c (paper eq. 3, plus the constant
// that the square-root form carries as ½‖r_m‖²; it keeps E_m ≥ 0 and the energies of both storages
// comparable, e.g. for a relative-decrease stopping rule).
template <typename Scalar>
struct HessianPrior {
  MatX<Scalar> H;
  VecX<Scalar> b;
  Scalar c = 0;
};

template <typename Scalar>
struct PinvOptions {
  RankThresholdMode mode = RankThresholdMode::kRelative;
  // Negative: the default of the mode (n · ε relative).
  Scalar threshold = Scalar(-1);
};

template <typename Scalar>
struct PseudoInverse {
  MatX<Scalar> H_pinv;
  int rank = 0;
  Scalar threshold_used = 0;  // the absolute eigenvalue cut-off that was applied
};

// Pseudo-inverse of a symmetric matrix through its eigendecomposition (lower triangle is read).
template <typename Scalar>
PseudoInverse<Scalar> pseudoInverseSelfAdjoint(const MatX<Scalar>& H,
                                               const PinvOptions<Scalar>& options = {});

template <typename Scalar>
struct SchurMarginalization {
  HessianPrior<Scalar> prior;  // (H̃, b̃) over the kept variables; c = −½ b_μᵀ H_μμ⁺ b_μ
  int marg_rank = 0;           // rank of H_μμ as decided by the pseudo-inverse
  Scalar threshold_used = 0;
  Status status;
};

template <typename Scalar>
SchurMarginalization<Scalar> schurMarginalize(const MatX<Scalar>& H, const VecX<Scalar>& b,
                                              int n_marg, const PinvOptions<Scalar>& options = {});

template <typename Scalar>
struct LdltSqrt {
  SqrtPrior<Scalar> prior;  // J = √D Lᵀ P (square, zero rows where D was clamped), r
  int n_clamped = 0;        // pivots D_i < 0 (or below the relative floor) set to 0
  int rank = 0;             // pivots D_i > 0
  Status status;
};

template <typename Scalar>
LdltSqrt<Scalar> hessianToSqrtLdlt(const MatX<Scalar>& H, const VecX<Scalar>& b,
                                   Scalar relative_floor = Scalar(0));

}  // namespace marglab
