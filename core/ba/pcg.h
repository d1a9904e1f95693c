#pragma once
// Preconditioned conjugate gradients on the reduced camera system A x = b (A symmetric positive
// definite: the damped Schur complement), as Ceres' ConjugateGradientsSolver and rootba run it.
//
// Iteration k (x₀ = 0, r₀ = b, z = M⁻¹ r, p₀ = z₀):
//     α_k = ρ_k / p_kᵀ A p_k,  x += α_k p_k,  r −= α_k A p_k,  ρ_{k+1} = r_{k+1}ᵀ M⁻¹ r_{k+1},
//     β_k = ρ_{k+1} / ρ_k,     p_{k+1} = z_{k+1} + β_k p_k.
// Termination (Nash & Sofer's truncated-Newton rule, Ceres' and rootba's): with the quadratic
// Q(x) = ½ xᵀ A x − bᵀ x, which CG decreases monotonically in exact arithmetic,
//     stop when  k · (Q_k − Q_{k−1}) / Q_k < η        (forcing sequence η, 0.1),
// or when ‖r‖ ≤ ε ‖b‖ (solved to working precision), or after max_iterations (500).
// Numerical failure, recorded and returned as a Status (never thrown): p_kᵀ A p_k ≤ 0 or
// non-finite (A not positive definite in this precision), a non-finite iterate. An increase of Q,
// impossible in exact arithmetic, stops the iteration at the previous iterate and is reported in
// the summary's message (rootba's "non-decreasing CG").
//
// Ritz values. The CG coefficients are those of the Lanczos process on M⁻¹A: the tridiagonal
//     T_jj = 1/α_j + β_{j−1}/α_{j−1},   T_{j,j+1} = √β_j / α_j
// has eigenvalues (Ritz values) that converge to the extreme eigenvalues of M⁻¹A from inside; its
// smallest and largest bound the preconditioned system's spectrum from inside and their ratio the
// condition number CG saw (Golub & Van Loan §11.3.5). Computed once at the end, O(k²).

#include <functional>
#include <limits>
#include <string>

#include "core/common/eigen_types.h"
#include "core/common/status.h"

namespace marglab {

struct CgOptions {
  int max_iterations = 500;
  double eta = 0.1;
};

struct CgSummary {
  int iterations = 0;
  // NaN when no CG iteration ran (also for a trial that failed before CG).
  double ritz_min = std::numeric_limits<double>::quiet_NaN();
  double ritz_max = std::numeric_limits<double>::quiet_NaN();
  std::string message;
};

template <typename Scalar>
struct CgOperators {
  std::function<void(const VecX<Scalar>& x, VecX<Scalar>* Ax)> apply_A;
  std::function<void(const VecX<Scalar>& r, VecX<Scalar>* z)> apply_M_inverse;
};

template <typename Scalar>
Status preconditionedCg(const CgOperators<Scalar>& ops, const VecX<Scalar>& b,
                        const CgOptions& options, VecX<Scalar>* x, CgSummary* summary);

}  // namespace marglab
