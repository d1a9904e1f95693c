#pragma once
// Marginalization of window variables into the prior (paper §3.1.3, §4.2), one implementation per
// method, behind one interface:
//
//   QrMarginalizer     (qr, square-root storage): landmarks by nullspace projection (their Q2ᵀ
//                      rows), then the flat rank-revealing QR of [J_marg | J_keep | r] over the
//                      stacked landmark rows, the rows taken as they are and the old prior's rows;
//                      the new prior is the R rows of the kept columns (core/linalg/flat_qr.h).
//   SchurMarginalizer  (sc, either storage): Schur complement of the landmarks (3×3 blocks), then
//                      of the marginalized variables on the Hessian with a pseudo-inverse of H_μμ
//                      (eqs. 22–23, core/linalg/schur.h); a square-root prior is its LDLT √D Lᵀ P.
//
// Both start from the same gathered problem: the plan's landmarks linearized over the frames whose
// observations stay (rows beyond the three a landmark consumes carry pose information), the rows
// stacked as they are (IMU factors leaving, observations of landmarks that stay, landmarks of a
// dense prior that go, recovered factors on marginalized variables), the old prior. The new prior
// is laid out over the kept variables those touch, anchored at their first estimates x⁰, and
// stores its expansion at δ = 0 (r_m − J_m δ, b_m − H_m δ).

#include <memory>
#include <set>
#include <utility>
#include <vector>

#include "core/common/status.h"
#include "core/estimator/estimator_settings.h"
#include "core/estimator/window.h"

namespace marglab {

template <typename Scalar>
class Marginalizer {
 public:
  virtual ~Marginalizer() = default;
  // Replaces *prior by the marginal of the plan's factors and *prior over the kept variables.
  // qr_rank (may be null) receives the flat QR's total rank (−1 for the Schur complement).
  virtual Status marginalize(const Window<Scalar>& window, const MargPlan& plan,
                             MargPrior<Scalar>* prior, int* qr_rank) const = 0;
};

// The marginalizer of a method and prior storage, a combination variantProblem accepts (qr: the
// storage is sqrt, which the flat QR produces); the flat QR's rank threshold comes from the config.
template <typename Scalar>
std::unique_ptr<Marginalizer<Scalar>> makeMarginalizer(MargMethod method,
                                                       const PriorStorage& storage,
                                                       const EstimatorSettings& config);

// The prior Hessian H_m, in double, that marginalizing `plan` with `method` makes of `prior`
// (a copy; the window stays as it is): qr produces a plain square root (and needs one, or an empty
// prior, to start from), sc a plain Hessian (with the window config's psd_hessian_prior). For
// comparing the methods on one window (the equivalence tests: the same H_m up to rounding).
template <typename Scalar>
Status trialMarginalization(const Window<Scalar>& window, MargPrior<Scalar> prior,
                            const MargPlan& plan, MargMethod method, MatXd* H_m);

// The Schur marginalization's Hessian system over [marginalized | kept] before the marginalized
// variables are eliminated — the landmarks' Schur complements, the direct rows and, with
// add_prior, the old prior at its current δ — exactly as SchurMarginalizer forms it (same
// operations, same order); the new prior's layout (anchored at the kept variables' first
// estimates) and its δ. For measuring the rounding of each stage (marg_rounding.h).
template <typename Scalar>
struct SchurSystem {
  MatX<Scalar> H;
  VecX<Scalar> b;
  int n_marg = 0;
  MargPrior<Scalar> layout;  // blocks only
  VecX<Scalar> new_delta;
};
template <typename Scalar>
Status schurSystem(const Window<Scalar>& window, const MargPlan& plan,
                   const MargPrior<Scalar>& prior, bool add_prior, SchurSystem<Scalar>* out);

// The relative floor below which the new prior's LDLT pivots are set to 0 (hessianToSqrtLdlt):
// NumericTraits' n·ε for the gauge-exact projection g, else 0 (only negative pivots, which no
// square root can keep).
template <typename Scalar>
Scalar ldltPivotFloor(PsdProjection psd, Eigen::Index n);

}  // namespace marglab
