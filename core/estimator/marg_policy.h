#pragma once
// What leaves the window after each frame (the estimator's marginalization policy, paper §3.2):
//   VO   — a non-keyframe current frame is removed with its observations;
//   VIO  — when there are more than max_states states, the oldest goes: a keyframe loses its
//          speed-bias block (its pose stays), a non-keyframe its whole state (its observations are
//          dropped); the IMU factor leaving it joins the prior;
//   both — when there are more than max_kfs keyframes one pose-only keyframe is marginalized (the
//          oldest of all but the newest two with a share < marg_connected_share of its landmarks
//          still observed, else the DSO distance score) with the landmarks it hosts (its
//          observations of other landmarks are dropped: keeps the prior sparse); landmarks whose
//          track ended are marginalized right away.
// Strategies dense / nfr (VIO) keep the keyframe's landmarks that other frames still see, as world
// points in the new prior, with the keyframe's observations of them.

#include <cstdint>
#include <optional>
#include <set>

#include "core/estimator/config.h"
#include "core/estimator/marginalizer.h"
#include "core/estimator/window.h"

namespace marglab {

template <typename Scalar>
class MarginalizationPolicy {
 public:
  explicit MarginalizationPolicy(const EstimatorConfig& config) : config_(config) {}

  // The plan after frame `current`; observations the plan drops are erased from the window now,
  // and (dense / nfr) kept landmarks become world points. *kf: the keyframe marginalized, if any.
  MargPlan plan(Window<Scalar>& w, int64_t current, std::optional<int64_t>* kf) const;
  // The oldest VIO state (keyframe: its speed-bias; otherwise the whole state); nullopt for VO or
  // with no state to spare (force: even within max_states).
  std::optional<MargPlan> stateMarginalization(const Window<Scalar>& w, bool force = false) const;
  // Keyframe `frame_id` with the landmarks it hosts.
  MargPlan keyframeMarginalization(const Window<Scalar>& w, int64_t frame_id) const;
  // Strategy dense / nfr in effect (VIO only).
  bool keepsLandmarks(const Window<Scalar>& w) const {
    return w.isVio() && config_.marg_strategy != MargStrategy::kDiscard;
  }

 private:
  std::optional<int64_t> selectKeyframe(const Window<Scalar>& w, int64_t current,
                                        const std::set<VarKey>& marg_vars) const;
  void planKeptLandmarks(Window<Scalar>& w, int64_t kf, std::set<int64_t>* marg_landmarks,
                         MargPlan* plan) const;

  EstimatorConfig config_;
};

}  // namespace marglab
