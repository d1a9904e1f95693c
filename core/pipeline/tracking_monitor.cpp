#include "core/pipeline/tracking_monitor.h"

#include <fmt/core.h>

#include <algorithm>

namespace marglab {

bool TrackingMonitor::inconsistent(const FrameResult& result) const {
  return result.n_checked >= std::max(min_observations_, 1) &&
         result.n_inconsistent > max_inconsistent_share_ * result.n_checked;
}

std::string TrackingMonitor::update(int frame_index, const FrameResult& result) {
  const bool starved = result.n_connected < min_observations_;
  if (frame_index == 0 || (!starved && !inconsistent(result))) {
    lost_ = 0;
    return "";
  }
  if (++lost_ < max_frames_) return "";
  if (starved) {
    return fmt::format(
        "tracking lost: {} frame(s) in a row with fewer than {} observations of the window's "
        "landmarks (this frame: {})",
        lost_, min_observations_, result.n_connected);
  }
  return fmt::format(
      "tracking lost: {} frame(s) in a row in which more than {:g} % of the observations of the "
      "window's landmarks lie farther than {:g} px from their projection after the optimization "
      "(this frame: {} of {})",
      lost_, 100 * max_inconsistent_share_, inconsistent_px_, result.n_inconsistent,
      result.n_checked);
}

}  // namespace marglab
