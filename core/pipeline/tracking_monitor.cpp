#include "core/pipeline/tracking_monitor.h"

#include <fmt/core.h>

namespace marglab {

std::string TrackingMonitor::update(int frame_index, const FrameResult& result) {
  if (frame_index == 0 || result.n_connected >= min_observations_) {
    starved_ = 0;
    return "";
  }
  if (++starved_ < max_frames_) return "";
  return fmt::format(
      "tracking lost: {} frame(s) in a row with fewer than {} observations of the window's "
      "landmarks (this frame: {})",
      starved_, min_observations_, result.n_connected);
}

}  // namespace marglab
