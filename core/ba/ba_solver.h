#pragma once
// `marglab ba`'s solvers on a loaded (normalized, perturbed) BAL problem: the elimination
// ablation ns-f32 / ns-f64 / sc-f32 / sc-f64 (landmark_system.h, Levenberg–Marquardt below) and
// the Ceres peers on the same model, start and loss (ceres_ba.h).
//
// The LM loop is rootba's (solver/bal_bundle_adjustment.cpp): iteration 0 evaluates the cost;
// each later iteration tries one step δ for the current λ (after a new linearization when the
// previous step was accepted), with
//     ρ = (cost − cost(x ⊕ δ)) / (−model change),
// accepted when the model change is negative and ρ > 0. A step that cannot be computed (a landmark
// or preconditioner block that fails, CG's non-positive curvature, a non-finite step or cost) is a
// rejected iteration with its reason, never an abort.

#include "core/ba/ba_options.h"
#include "core/ba/ba_state.h"
#include "core/ba/bal_problem.h"

namespace marglab {

// `solution`, when not null, receives the final cameras and points: an f32 solver's float state
// exactly (every float is a double), Ceres' angle-axis cameras through Rodrigues in double.
BaResult solveBundleAdjustment(const BalProblem& problem, const BaOptions& options,
                               BalState<double>* solution = nullptr);

}  // namespace marglab
