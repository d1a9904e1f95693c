#include "core/estimator/marg_policy.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/common/scalar.h"
#include "core/geometry/stereographic.h"

namespace marglab {

template <typename Scalar>
std::optional<MargPlan> MarginalizationPolicy<Scalar>::stateMarginalization(const Window<Scalar>& w,
                                                                            bool force) const {
  const std::vector<int64_t> states = w.stateIds();
  if (!w.isVio() || states.size() < 2 ||
      (!force && static_cast<int>(states.size()) <= config_.max_states)) {
    return std::nullopt;
  }
  const int64_t oldest = states.front();
  MargPlan plan;
  plan.vars.insert({oldest, StateBlock::kSpeedBias});
  if (!w.frames.at(oldest).is_keyframe) {
    plan.vars.insert({oldest, StateBlock::kPose});
    plan.drop_obs_frames.insert(oldest);
  }
  if (w.imu_links.count(oldest) != 0) plan.imu_links.push_back(oldest);
  return plan;
}

template <typename Scalar>
MargPlan MarginalizationPolicy<Scalar>::keyframeMarginalization(const Window<Scalar>& w,
                                                                int64_t frame_id) const {
  MargPlan plan;
  plan.vars.insert({frame_id, StateBlock::kPose});
  for (const auto& [id, lm] : w.landmarks) {
    if (lm.host == frame_id) plan.landmarks.push_back(id);
  }
  return plan;
}

template <typename Scalar>
std::optional<int64_t> MarginalizationPolicy<Scalar>::selectKeyframe(
    const Window<Scalar>& w, int64_t current, const std::set<VarKey>& marg_vars,
    bool current_dropped) const {
  const std::vector<int64_t> kfs = w.keyframeIds();
  if (static_cast<int>(kfs.size()) <= config_.max_kfs) return std::nullopt;
  // Only pose-only keyframes (VIO: older than the states, or losing their speed-bias now).
  std::vector<int64_t> candidates;
  for (auto it = kfs.begin(); it != kfs.end() - 2; ++it) {
    if (!w.frames.at(*it).has_speed_bias || marg_vars.count({*it, StateBlock::kSpeedBias}) != 0) {
      candidates.push_back(*it);
    }
  }
  if (candidates.empty()) return std::nullopt;
  for (int64_t c : candidates) {
    int hosted = 0, connected = 0;
    for (const auto& [id, lm] : w.landmarks) {
      if (lm.host != c) continue;
      ++hosted;
      connected += !current_dropped && lm.obs.count(current) != 0 ? 1 : 0;
    }
    if (hosted == 0 || connected < config_.marg_connected_share * hosted) return c;
  }
  // DSO's distance score: prefer frames far from the newest keyframe but close to the others.
  const Vec3<Scalar> t_last = w.frames.at(kfs.back()).T_w_i.translation();
  int64_t best = candidates.front();
  Scalar best_score = -1;
  for (int64_t c : candidates) {
    const Vec3<Scalar> t_c = w.frames.at(c).T_w_i.translation();
    Scalar sum = 0;
    for (int64_t j : kfs) {
      if (j != c) {
        sum += Scalar(1) / ((t_c - w.frames.at(j).T_w_i.translation()).norm() + Scalar(1e-5));
      }
    }
    const Scalar score = std::sqrt((t_c - t_last).norm()) * sum;
    if (score > best_score) {
      best_score = score;
      best = c;
    }
  }
  return best;
}

template <typename Scalar>
MargDecision MarginalizationPolicy<Scalar>::decide(const Window<Scalar>& w, int64_t current) const {
  MargDecision decision;
  MargPlan& plan = decision.plan;
  std::set<int64_t> marg_landmarks;
  for (const auto& [id, lm] : w.landmarks) {
    if (lm.obs.count(current) == 0) marg_landmarks.insert(id);  // track lost
  }
  if (!w.isVio() && !w.frames.at(current).is_keyframe) plan.drop_obs_frames.insert(current);
  if (const auto state_plan = stateMarginalization(w)) {
    plan.vars = state_plan->vars;
    plan.imu_links = state_plan->imu_links;
    plan.drop_obs_frames.insert(state_plan->drop_obs_frames.begin(),
                                state_plan->drop_obs_frames.end());
  }
  decision.edits.erase_frames = plan.drop_obs_frames;
  decision.keyframe =
      selectKeyframe(w, current, plan.vars, plan.drop_obs_frames.count(current) != 0);
  if (const std::optional<int64_t> kf = decision.keyframe) {
    plan.vars.insert({*kf, StateBlock::kPose});
    if (keepsLandmarks(w)) {
      planKeptLandmarks(w, *kf, &marg_landmarks, &decision);
    } else {
      for (const auto& [id, lm] : w.landmarks) {
        if (lm.host == *kf) {
          marg_landmarks.insert(id);
        } else if (marg_landmarks.count(id) == 0 && lm.obs.count(*kf) != 0) {
          decision.edits.erase_obs.emplace_back(id, *kf);  // keeps the prior sparse (§3.2.2)
        }
      }
    }
  }
  // Basalt's policy: an event that marginalizes no state leaves the lost landmarks in the window.
  if (config_.lost_landmarks == LostLandmarkMarg::kWithState && plan.vars.empty()) {
    marg_landmarks.clear();
  }
  // Landmarks of a dense prior are variables of the prior: they go as such.
  for (int64_t track : w.priorLandmarks()) {
    if (marg_landmarks.erase(track) != 0) plan.vars.insert({track, StateBlock::kLandmark});
  }
  plan.landmarks.assign(marg_landmarks.begin(), marg_landmarks.end());
  return decision;
}

template <typename Scalar>
void MarginalizationPolicy<Scalar>::planKeptLandmarks(const Window<Scalar>& w, int64_t kf,
                                                      std::set<int64_t>* marg_landmarks,
                                                      MargDecision* decision) const {
  // Below this inverse distance (1 km) a landmark is as good as at infinity: no world point.
  const Scalar min_rho = Scalar(1e-3);
  const std::set<int64_t>& erased = decision->edits.erase_frames;
  for (const auto& [id, lm] : w.landmarks) {
    if (marg_landmarks->count(id) != 0) continue;
    const bool seen_in_kf = lm.obs.count(kf) != 0;
    if (!seen_in_kf && lm.host != kf) continue;
    const bool seen_elsewhere =
        std::any_of(lm.obs.begin(), lm.obs.end(), [kf, &erased](const auto& entry) {
          return entry.first != kf && erased.count(entry.first) == 0;
        });
    if (!seen_elsewhere || (!lm.world() && lm.param.z() < min_rho)) {
      marg_landmarks->insert(id);
      continue;
    }
    // Re-parametrized as a world point before it joins the prior: a free variable, so no change
    // of variables of any prior is needed, and its host may leave the window later.
    if (!lm.world()) decision->edits.to_world.push_back(id);
    if (!seen_in_kf) continue;
    // nfr needs a positive definite Λ_t: a monocular observation alone gives the landmark a
    // rank-2 prior (no depth), so it is dropped unless a factor anchored at kf fixes the depth.
    const bool anchored_at_kf =
        std::any_of(lm.nfr.begin(), lm.nfr.end(), [kf](const auto& f) { return f.frame == kf; });
    if (config_.marg_strategy == MargStrategy::kNfr && !lm.obs.at(kf).has_right &&
        !anchored_at_kf) {
      decision->edits.erase_obs.emplace_back(id, kf);
      continue;
    }
    decision->plan.kept_landmark_obs.emplace_back(id, kf);
  }
}

template <typename Scalar>
void applyEdits(const WindowEdits& edits, Window<Scalar>* w) {
  for (int64_t f : edits.erase_frames) {
    for (auto& [id, lm] : w->landmarks) lm.obs.erase(f);
  }
  for (const auto& [track, frame] : edits.erase_obs) w->landmarks.at(track).obs.erase(frame);
  for (int64_t track : edits.to_world) {
    auto& lm = w->landmarks.at(track);
    lm.param = w->poseOf(lm.host) * (w->T_i_c(0) * landmarkToPoint<Scalar>(lm.param));
    lm.host = -1;
  }
}

#define MARGLAB_INST(S)                    \
  template class MarginalizationPolicy<S>; \
  template void applyEdits<S>(const WindowEdits&, Window<S>*);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
