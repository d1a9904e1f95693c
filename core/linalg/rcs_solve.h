#pragma once
// Levenberg–Marquardt step on the reduced camera system (docs/design.md §3, LM):
//     (H + D) δ = −b,   D_ii = max(λ · H_ii, λ_min),
// solved by LDLT (Eigen's, with diagonal pivoting). The damping rule bounds the step along
// directions the data does not constrain (gauge, weakly observed variables) instead of letting a
// singular H fail. Failure — a non-positive pivot, a non-finite step — is returned as a Status.
// With solve_indefinite a non-positive pivot is no failure: Eigen's LDLT (diagonal pivoting,
// P(H + D)Pᵀ = L D Lᵀ with D of any sign) solves a symmetric indefinite system as well, and its
// solution is returned — what Basalt's optimize() does; only a non-finite step then fails.
// With a preconditioning (core/linalg/preconditioner.h) the damped system is solved as
// (Pᵀ(H + D)P) y = −Pᵀb, δ = P y, P built from the damped H's 3×3 diagonal blocks.

#include "core/common/eigen_types.h"
#include "core/common/status.h"
#include "core/linalg/preconditioner.h"

namespace marglab {

template <typename Scalar>
struct DampedSolve {
  VecX<Scalar> delta;
  Status status;
};

// The LM damping of one diagonal entry.
template <typename Scalar>
inline Scalar lmDamping(Scalar H_ii, Scalar lambda, Scalar lambda_min) {
  return std::max(lambda * H_ii, lambda_min);
}

// H is taken by value and damped in place; only its lower triangle is read by the LDLT.
template <typename Scalar>
DampedSolve<Scalar> solveDampedLdlt(MatX<Scalar> H, const VecX<Scalar>& b, Scalar lambda,
                                    Scalar lambda_min,
                                    Preconditioning preconditioning = Preconditioning::kNone,
                                    bool solve_indefinite = false);

}  // namespace marglab
