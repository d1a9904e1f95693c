// The tracking-failure rule (core/pipeline/tracking_monitor.h): a run fails after
// max_tracking_loss_frames frames in a row with fewer than min_tracked_observations observations of
// the window's landmarks; a frame above the bound resets the count; the first frame never counts.

#include <gtest/gtest.h>

#include "core/pipeline/tracking_monitor.h"

namespace marglab {
namespace {

FrameResult withConnected(int n) {
  FrameResult result;
  result.n_connected = n;
  return result;
}

TEST(TrackingMonitor, FailsAfterTheConfiguredRunOfStarvedFrames) {
  EstimatorConfig config;
  config.min_tracked_observations = 10;
  config.max_tracking_loss_frames = 3;
  TrackingMonitor monitor(config);
  EXPECT_EQ(monitor.update(0, withConnected(0)), "");  // the first frame creates the landmarks
  EXPECT_EQ(monitor.update(1, withConnected(9)), "");
  EXPECT_EQ(monitor.update(2, withConnected(9)), "");
  EXPECT_EQ(monitor.update(3, withConnected(10)), "");  // at the bound: not starved, resets
  EXPECT_EQ(monitor.update(4, withConnected(0)), "");
  EXPECT_EQ(monitor.update(5, withConnected(3)), "");
  const std::string reason = monitor.update(6, withConnected(2));
  EXPECT_NE(reason.find("tracking lost: 3 frame(s) in a row with fewer than 10"), std::string::npos)
      << reason;
  EXPECT_NE(reason.find("(this frame: 2)"), std::string::npos) << reason;
}

TEST(TrackingMonitor, ZeroMinimumNeverFails) {
  EstimatorConfig config;
  config.min_tracked_observations = 0;
  config.max_tracking_loss_frames = 1;
  TrackingMonitor monitor(config);
  for (int k = 0; k < 10; ++k) EXPECT_EQ(monitor.update(k, withConnected(0)), "");
}

}  // namespace
}  // namespace marglab
