#pragma once
// The rounding one Schur-complement marginalization of a Hessian prior injects, stage by stage
// (README "Where we depart", item 6; config key diagnostics.marg_rounding). From the same inputs —
// the window as it was marginalized (widened exactly to double) and the old prior (promoted) — the
// marginal is computed in double (the reference S_a = Schur₆₄(A₆₄), A the Hessian system over
// [marginalized | kept] of marginalizer.h's schurSystem) and the run's Scalar result S_d is
// reached one stage at a time, each difference the rounding that stage adds:
//   new     S_b − S_a,  S_b = Schur₆₄(A₆₄ + (N_S − N₆₄)): the new factors' system N (linearization,
//                       the landmarks' 3×3 Schur complements, the direct rows) formed in Scalar;
//   add     S_c − S_b,  S_c = Schur₆₄(A_S): the old prior added to N in Scalar;
//   schur   S_d − S_c,  S_d = Schur_S(A_S): the marginalized poses eliminated in Scalar (its result
//                       is the stored prior, so this includes the storage rounding);
// the sum is S_d − S_a exactly. `floor` is ‖fl(S_a) − S_a‖: the rounding of storing the exact
// marginal alone. Every matrix norm is Frobenius, relative to ‖S_a‖. The gauge block of an
// error E is Gᵀ E G with G the orthonormalized 6 rigid motions of the new prior's layout at its
// linearization points (gauge.h): how much of the error lands where only the gauge prior (through
// the marginalizations) holds the window; its trace is signed (negative: the error takes
// information away along the rigid motions). The b shift: the stored b_m = b̃ − H̃ δ against the
// same in double. For f64 runs every rounding is 0 and the rows still give the prior's spectrum.

#include <cstdint>
#include <string>
#include <vector>

#include "core/common/status.h"
#include "core/estimator/marg_prior.h"
#include "core/estimator/variant.h"
#include "core/estimator/window.h"

namespace marglab {

struct MargRoundingStage {
  double rel_fro = 0;      // ‖E‖_F / ‖S_a‖_F
  double gauge_share = 0;  // ‖Gᵀ E G‖_F / ‖E‖_F (0 when E = 0)
  double gauge_trace = 0;  // trace(Gᵀ E G), absolute
};

struct MargRoundingRow {
  int64_t frame_index = -1;  // set by the caller
  int n = 0;                 // columns of the new prior
  int n_marg = 0;            // columns eliminated (poses)
  int n_landmarks = 0;       // landmarks eliminated with them
  MargRoundingStage total, new_factors, add_prior, schur;
  double floor_rel_fro = 0;  // ‖fl(S_a) − S_a‖_F / ‖S_a‖_F
  double b_rel = 0;  // ‖b_S − b₆₄‖ / ‖b₆₄‖ of the stored b_m (NaN when b₆₄ = 0)
  double sigma_max = 0;      // largest eigenvalue of S_a
  double eig_min_run = 0;    // smallest eigenvalue of the run's prior S_d (signed)
  double eig_min_ref = 0;    // smallest eigenvalue of S_a (signed)
  double gauge_min_run = 0;  // smallest eigenvalue of Gᵀ S_d G: the prior's least information
  double gauge_min_ref = 0;  //   along a rigid motion of the window; the same of S_a
  double translation_min_ref = 0;  // the same over the window's translations alone: ≈
                                   // gauge_min_ref when the least-informed rigid motion is one
};

// Measures one event: `window` as it was marginalized, `before` / `after` the prior. Needs a plain
// Hessian storage (sq, sqc, sqg: not preconditioned) and a VO window; an error otherwise.
// `variant` is the run's (for restoring the window in double).
template <typename Scalar>
Status measureMargRounding(const Window<Scalar>& window, const MargPlan& plan,
                           const MargPrior<Scalar>& before, const MargPrior<Scalar>& after,
                           const Variant& variant, MargRoundingRow* row);

// The rows as CSV (a header line, then one line per row, %.9g).
std::string margRoundingCsv(const std::vector<MargRoundingRow>& rows);

}  // namespace marglab
