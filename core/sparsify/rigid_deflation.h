#pragma once
// Rigid-motion deflation of the factors nfr recovers (`[marginalization] nfr_rigid_deflation`;
// README "Where we depart from the paper", item 3): the causal test of the reading that the
// paper topology loses over whole sequences because its unary factors are more confident than the
// dense prior about where the window as a whole sits.
//
// Problem. nfr (core/sparsify/nfr.h) replaces the dense prior, information Λ_d (nfr.h's Λ_t), by
// factors of information Λ_s = H_sᵀΛ_rH_s, KLD-optimal but, with unary factors, larger than Λ_d
// along the rigid motions of the window. E = [ε_x ε_y ε_z ε_roll ε_pitch ε_yaw] (n × 6) are the
// rigid directions of core/diagnostics/gauge.h over the blanket — the first six columns of
// /sparsify info_dense; its seventh, the random direction, is the control and is not a rigid
// motion. Wanted: Λ_s' with
//   (i)   Λ_s' δ = Λ_s δ for every δ in the Λ_s-orthogonal complement of span E (EᵀΛ_sδ = 0);
//   (ii)  Λ_s' ⪯ Λ_s on span E, and no rigid direction more confident than the dense prior:
//         EᵀΛ_s'E ⪯ G_d = EᵀΛ_dE;
//   (iii) the least such correction, in tr(Λ_s⁻¹(Λ_s − Λ_s')) (the first-order loss of
//         log det Λ_s: information removed, relative to what was there);
//   (iv)  Λ_s' ⪰ 0.
//
// Which orthogonality. Write δ = E a + y with EᵀΛ_s y = 0. Then δᵀΛ_sδ = aᵀG_s a + yᵀΛ_s y with no
// cross term (G_s = EᵀΛ_sE): under N(0, Λ_s⁻¹) the rigid-motion coordinates a and the remainder y
// are independent, so the information on a can change while the distribution of y stays, and
// Λ_s − Λ_s E K EᵀΛ_s is ⪰ 0 iff G_s − G_s K G_s ⪰ 0: (iv) reduces to a 6 × 6 condition. In the
// Euclidean complement (Eᵀy = 0) a correction E Δ Eᵀ also keeps y's form, but Λ_s + E Δ Eᵀ ⪰ 0
// needs Δ ⪰ −(EᵀΛ_s⁻¹E)⁻¹, a bound the measured excess need not meet. So "orthogonal" is in the
// Λ_s inner product, and a random direction "orthogonal to the rigid motions" keeps its
// information only in that sense.
//
// Solution. Whiten span E by G_s = V S Vᵀ: W = V₊ S₊^(−1/2) over the eigenvalues above the rank
// threshold (NumericTraits<double>::pinvRelativeTolerance(6) · s_max; along the others Λ_s has no
// information to remove), M = WᵀG_dW = P diag(μ) Pᵀ. The f_j = E W p_j are Λ_s-orthonormal and
// Λ_d-orthogonal with f_jᵀΛ_d f_j = μ_j, the ratio dense / sparse along them. In these coordinates
// the constraints read X ⪯ I and X ⪯ diag(μ): the deflation D = I − X is ⪰ 0 and
// ⪰ I − diag(μ). Every such D has tr D ≥ Σ_j (1 − μ_j)₊ (tr D ≥ tr D P₊ ≥ tr (I − diag μ) P₊,
// P₊ the projector onto μ_j < 1), with equality for D = diag((1 − μ_j)₊). So
//   Λ_s' = Λ_s − Σ_{μ_j < 1} (1 − μ_j) (Λ_s f_j)(Λ_s f_j)ᵀ:
// along each f_j with μ_j < 1 the information drops to Λ_d's, μ_j; everything else keeps its own.
// (An excess 1 − μ_j below 100 k ε is taken as rounding of M, not deflated.)
// When every μ_j ≤ 1 (the measured case: Λ_s is 2.1–2.7× Λ_d along the rigid motions)
// EᵀΛ_s'E = G_d, so every rigid direction carries exactly the dense prior's information; when
// every μ_j ≥ 1 nothing changes; in between a direction mixing deflated and kept f_j ends between
// the two (by (ii)).
//
// Onto the factors. The pose–landmark and relative-pose factors are invariant under a rigid motion
// of the world (their H_i ε = 0 at x̄: the landmarks move with the poses), and the bias factors
// see none of it (biases are body-frame quantities): Λ_s ε = Λ_u ε, Λ_u = J_uᵀJ_u the information
// of the unary pose and velocity factors, J_u their whitened Jacobians at x̄ stacked (m rows; at
// z = h(x̄) the ⊟ Jacobians are the identity, so factor i's rows are W_i S_i on its variable's
// columns). With B = J_u E (m × 6), G_s = BᵀB and the q_j = J_u f_j = B W p_j are orthonormal in
// ℝᵐ. On the stacked whitened residuals e = [e_1; …; e_k] of those factors
//   A = I − Σ_{μ_j < 1} (1 − √μ_j) q_j q_jᵀ,      AᵀA = I − Σ_{μ_j < 1} (1 − μ_j) q_j q_jᵀ,
// so J_uᵀAᵀAJ_u = Λ_u − Σ (1 − μ_j)(Λ_u f_j)(Λ_u f_j)ᵀ and the factors' information is Λ_s'. A is
// symmetric with eigenvalues √μ_j and 1: ½‖A e(x)‖² is a least-squares residual, so (iv) holds by
// construction, with no factorization to fail — also for μ_j = 0 (the dense prior free along
// f_j), where A loses rank. The correction couples all the unary pose and velocity factors of an
// event, so they become one joint nonlinear factor ½‖A e(x)‖², relinearized as they were (bias
// factors stay unary); without a deflated direction A = I and they stay as they are.
//
// Cost and KLD. log det Λ_s' − log det Λ_s = Σ_{μ_j < 1} log μ_j (−∞ when a μ_j is 0);
// ⟨Λ_s' − Λ_s, Σ_t⟩ = −Σ (1 − μ_j) g_jᵀΣ_t g_j with g_j = Λ_u f_j = J_uᵀ q_j. Everything here is
// in double: a 6 × 6 problem whose inputs the estimator forms in double for /sparsify anyway.

#include "core/common/eigen_types.h"
#include "core/common/status.h"

namespace marglab {

struct RigidDeflation {
  Eigen::MatrixXd A;   // m × m; the identity when no direction is deflated
  Eigen::MatrixXd Q;   // m × d: the q_j of the deflated directions
  Eigen::VectorXd mu;  // their μ_j ∈ [0, 1), clamped at 0 against rounding
  Status status;
  int deflated() const { return static_cast<int>(mu.size()); }
  // log det Λ_s' − log det Λ_s.
  double logDetChange() const;
};

// B = J_u E (m × k, k ≤ 6 rigid directions), G_d = EᵀΛ_dE (k × k, the lower triangle is read).
// A non-finite input is a Status error (the caller keeps the dense prior).
RigidDeflation rigidDeflation(const Eigen::MatrixXd& B, const Eigen::MatrixXd& G_d);

}  // namespace marglab
