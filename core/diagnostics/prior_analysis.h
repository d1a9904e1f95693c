#pragma once
// Spectrum of a marginalization prior (docs/design.md §4, paper §5.2, Figs. 1, 4–6).
//
// The prior of the sliding window is E_m(x⁰ + Δx) = const + b_mᵀΔx + ½ ΔxᵀH_mΔx with
//   squared storage      (H_m, b_m) as stored (eq. 3),
//   square-root storage  H_m = J_mᵀJ_m, b_m = J_mᵀr_m (eq. 4), formed here in double.
// Every diagnostic is computed in double after converting the stored prior (paper §5.2), so the
// analysis itself adds only double-precision rounding to whatever the estimator's precision did.
//
// analyzePrior computes all eigenvalues λ_1 ≤ … ≤ λ_n of the symmetric part ½(H_m + H_mᵀ) (the
// quadratic form only sees the symmetric part; a squared f32 prior may be slightly asymmetric)
// with Eigen's SelfAdjointEigenSolver, and reports
//   sigma_min = λ_1, sigma_max = λ_n   (signed: the paper's "σ_min" of an indefinite prior is < 0),
//   τ = n · ε_f64 · max_i |λ_i|        the numerical-rank rule of Golub & Van Loan §5.4.1
//                                      (NumericTraits<double>::pinvRelativeTolerance(n)); the
//                                      eigenvalues of a symmetric matrix are computed with an
//                                      absolute error of O(ε‖H‖), so |λ| ≤ τ is indistinguishable
//                                      from 0 by the double analysis itself,
//   n_negative = #{λ_i < −τ}           negative beyond the analysis' own rounding: the stored
//                                      prior is indefinite (e.g. squared f32 priors, Fig. 1),
//   rank = #{|λ_i| > τ}.
// A gauge-free prior has rank n − 4 (VIO) or n − 6 (VO); a vanished nullspace shows as rank n
// with a large positive σ_min, an indefinite prior as n_negative > 0.

#include <Eigen/Core>

#include "core/common/eigen_types.h"

namespace marglab {

struct PriorSpectrum {
  VecXd eigenvalues;       // ascending; size n (all NaN when the analysis failed)
  double sigma_min = 0.0;  // λ_1 (NaN for n = 0 or a failed analysis)
  double sigma_max = 0.0;  // λ_n
  double tolerance = 0.0;  // τ = n ε max|λ|
  int n_negative = 0;      // λ < −τ
  int rank = 0;            // |λ| > τ
  bool valid = false;      // false if H_m is empty, has non-finite entries or the solver failed
};

PriorSpectrum analyzePrior(const MatXd& H_m);

// H_m = J_mᵀJ_m and b_m = J_mᵀr_m of a square-root prior, in double.
MatXd hessianFromSqrt(const MatXd& J_m);
VecXd gradientFromSqrt(const MatXd& J_m, const VecXd& r_m);

}  // namespace marglab
