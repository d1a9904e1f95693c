#pragma once
// An affine patch tracker: inverse-compositional Lucas–Kanade (Baker & Matthews, "Lucas-Kanade 20
// Years On", IJCV 2004) with a 6-parameter affine warp, for the temporal tracks whose
// translation-only LK (optical_flow.h, step 2) fails under the perspective scaling of forward
// driving: a point 5 m ahead of a car doing 1.2 m per frame grows by 1.3× between frames, and the
// translation model's residual then stays large at the patch's edges.
//
// Model. Template T(u) = I_from(x_from + u) on the (2r+1)² grid u ∈ [−r, r]²; warp into I_to
//   W(u; A, x) = x + A u     (A: 2×2, x: the tracked point).
// Brightness: both patches are divided by their mean (a gain change between frames cancels), so
// the residual is  e(u) = I_to(W(u)) / μ_to − T(u) / μ_T.
// Inverse compositional step: with the increment warp W_Δ(u) = Δt + (I + ΔA) u, linearized about
// Δ = 0 on the template side, e(u) ≈ e0(u) − g(u)ᵀ J(u) Δ, where g(u) = ∇T(u) / μ_T (central
// differences) and J(u) = ∂W_Δ/∂Δ = [[u₁ u₂ 0 0 1 0], [0 0 u₁ u₂ 0 1]] for Δ = (ΔA₁₁ ΔA₁₂ ΔA₂₁
// ΔA₂₂ Δt₁ Δt₂). The normal equations H Δ = Σ (gᵀJ)ᵀ e0 have H = Σ (gᵀJ)ᵀ(gᵀJ), a constant of the
// template (computed once). The update composes the inverse increment:
//   W ← W ∘ W_Δ⁻¹:  A ← A (I + ΔA)⁻¹,  x ← x − A_new Δt.
// Coarse to fine: on pyramid levels l = L−1 … 1 (x scaled by 2^−l; A is scale-free) only the
// shift is estimated with A held at its start (Δ = (0 0 0 0 Δt), the 2×2 translation block of H):
// a coarse level's few pixels of a small patch cannot fix six parameters, and the start's A (the
// predicted scale) is what makes the coarse levels' shift right. Level 0 estimates all six
// (PatchWarp::kAffine) or again the shift under the given A (kShift: the patch compared after a
// known zoom, which the front-end uses: six parameters from an 11×11 patch slide along edges, and
// the shift under the predicted zoom recovers more tracks — README, "Real images", has the counts). Each level iterates until ‖Δt‖ < 0.01 px (coarse levels 0.1 px: they only bring the next
// level within reach) or max_iterations; converged: a last step < 0.05 px at level 0. Failed: H
// singular, A degenerate (det ≤ 0.25 or ≥ 4: more than 2× scaling) or the patch leaves the image.
// The converged result carries the zero-mean NCC of the template and the warped patch (the
// appearance check of optical_flow.h step 2, after the warp instead of a plain shift).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

namespace marglab {

enum class PatchWarp { kShift, kAffine };  // what level 0 estimates (see above)

struct AffinePatch {
  Eigen::Vector2d x = Eigen::Vector2d::Zero();      // tracked point in I_to (level-0 pixels)
  Eigen::Matrix2d A = Eigen::Matrix2d::Identity();  // local affine map I_from → I_to
  double ncc = -1;  // result only: zero-mean NCC of the template and the warped patch, level 0
};

// Tracks the patch of radius `radius` around x_from in `from` into `to` from the start `start`
// with the level-0 model `warp`.
// from, to: pyramids of 8-bit images, element l is level l (level 0 full resolution; only the
// first `levels` are used). Returns false when the iteration failed (see above); *result is then
// unspecified.
bool trackAffinePatch(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
                      const Eigen::Vector2d& x_from, const AffinePatch& start, PatchWarp warp,
                      int radius, int levels, int max_iterations, AffinePatch* result);

}  // namespace marglab
