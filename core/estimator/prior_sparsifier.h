#pragma once
// Strategy nfr (Hsiung et al., IROS 2018): after a keyframe marginalization the dense prior over
// its Markov blanket is replaced by nonlinear factors recovered from it (core/sparsify/nfr.h).
//
// Blanket. The prior's variables: poses, speed-bias blocks (split into velocity and bias) and
// landmarks as world points. Topology `paper`: unary factors on every pose, velocity and bias, and
// pose–landmark factors from the newest keyframe pose of the blanket (keyframes leave last);
// `joint-states`: one joint factor over all state blocks instead of the unary ones — the dense
// prior marginalized onto the states, gradient kept — plus the same pose–landmark factors;
// `relative-pose`: a unary factor on the anchor pose and a relative-pose factor between
// consecutive blanket poses (in frame order) instead of the unary pose factors, the rest as
// `paper` — a tree, so eq. 16 is its exact optimum.
//
// Regularization. Our blanket is only positive semi-definite in general (a keyframe pose that
// enters through landmark eliminations alone carries relative information), while the closed form
// needs Σ_t: it is recovered for Λ_t + εI, ε = 10 n ε_mach tr Λ_t, just above core/sparsify's rank
// threshold; the factors carry information of order ε along the directions Λ_t leaves free.
//
// Insertion. Unary and relative-pose factors join the window's factor list, pose–landmark ones
// their landmark's rows (landmarks are still eliminated per landmark). The prior is emptied (paper)
// or keeps the joint factor over the states (joint-states); variables no longer in a linear prior
// drop their first estimates.
//
// Information along the window's rigid motions. For the directions ε of core/diagnostics/gauge.h
// over the blanket (x, y, z, roll, pitch, yaw about the poses' centroid, a random unit direction),
// εᵀΛ_t ε of the dense prior and εᵀΛ_s ε of what replaces it (Λ_s = H_sᵀΛ_r H_s, plus the joint
// factor for joint-states; Λ_s = Λ_t when the prior stays dense). KLD-optimal factors match the
// marginal covariances of the factors' variables, not the information along a direction that moves
// every variable at once: a unary topology counts the uncertainty all blanket states share once per
// state, so Λ_s can exceed Λ_t along the rigid motions while falling below it elsewhere.
//
// Rigid deflation (option nfr_rigid_deflation, topology paper): the unary pose and velocity factors
// lose their information in excess of Λ_t's along x … yaw (the first six directions above), and
// only that, as core/sparsify/rigid_deflation.h derives; they then enter the window as one joint
// factor (Window::NfrJointFactor). Not for relative-pose: with one unary pose factor its Λ_s, like
// Λ_t, has next to nothing (~ the regularization ε) along the translations, so there is no excess
// to resolve from rounding. info_sparse, nnz_sparse and kld describe
// the deflated factors. A deflation that fails (non-finite input) keeps the dense prior, with the
// reason.

#include <string>

#include "core/common/eigen_types.h"
#include "core/diagnostics/gauge.h"
#include "core/estimator/estimator_settings.h"
#include "core/estimator/window.h"
#include "core/io/results_records.h"

namespace marglab {

// One keyframe marginalization of a dense / nfr run, as the estimator reports it: its /sparsify
// row (info_dense, info_sparse: εᵀΛε of Λ_t and Λ_s along the gauge directions, see above; kld NaN:
// kept dense), which the run completes with frame_index and t_ns, and what the file does not store.
struct SparsifyEvent : SparsifyRecord {
  std::string fallback_reason;  // why nfr kept the dense prior (empty otherwise)
};

// Size and non-zeros of the window's prior as the blanket of a keyframe event (strategy dense);
// returns Λ_t.
template <typename Scalar>
MatX<Scalar> describeBlanket(const Window<Scalar>& window, SparsifyEvent* event);

// Strategy nfr: replaces the window's prior by recovered factors, deflated along the rigid motions
// when rigid_deflation (topology paper; the config refuses the others); keeps it dense when the
// recovery fails (event->fallback_reason).
template <typename Scalar>
void sparsifyPrior(Window<Scalar>& window, SparsifyTopology topology, bool rigid_deflation,
                   SparsifyEvent* event);

}  // namespace marglab
