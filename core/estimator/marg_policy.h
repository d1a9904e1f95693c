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
//          track ended are marginalized right away (marginalization.lost_landmarks = "at-once"),
//          or with the next event that marginalizes a state ("with-state", Basalt's).
// Strategies dense / nfr (VIO) keep the keyframe's landmarks that other frames still see, as world
// points in the new prior, with the keyframe's observations of them.
// The policy only decides (decide() is const on the window); the estimator applies the decision's
// window edits (applyEdits) before it marginalizes the plan.

#include <cstdint>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "core/estimator/estimator_settings.h"
#include "core/estimator/marginalizer.h"
#include "core/estimator/window.h"

namespace marglab {

// What the window changes before a plan is marginalized: the observations the plan drops (every
// observation in erase_frames; single ones in erase_obs as (track, frame)) and the hosted landmarks
// that join a dense / nfr prior, re-parametrized as world points at the current poses.
struct WindowEdits {
  std::set<int64_t> erase_frames;
  std::vector<std::pair<int64_t, int64_t>> erase_obs;
  std::vector<int64_t> to_world;
};

// The decision after one frame: the plan, the keyframe it marginalizes (if any), and the edits.
struct MargDecision {
  MargPlan plan;
  std::optional<int64_t> keyframe;
  WindowEdits edits;
};

// Applies the edits in the order the decision assumed: erasures, then re-parametrizations.
template <typename Scalar>
void applyEdits(const WindowEdits& edits, Window<Scalar>* w);

template <typename Scalar>
class MarginalizationPolicy {
 public:
  explicit MarginalizationPolicy(const EstimatorSettings& config) : config_(config) {}

  // What leaves the window after frame `current`, judged on the window as it will be once the
  // decision's edits are applied.
  MargDecision decide(const Window<Scalar>& w, int64_t current) const;
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
  // current_dropped: the current frame's observations are erased (a VO non-keyframe).
  std::optional<int64_t> selectKeyframe(const Window<Scalar>& w, int64_t current,
                                        const std::set<VarKey>& marg_vars,
                                        bool current_dropped) const;
  void planKeptLandmarks(const Window<Scalar>& w, int64_t kf, std::set<int64_t>* marg_landmarks,
                         MargDecision* decision) const;

  EstimatorSettings config_;
};

}  // namespace marglab
