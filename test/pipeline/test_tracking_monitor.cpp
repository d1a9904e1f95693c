// The tracking-failure rule (core/pipeline/tracking_monitor.h): a run fails after
// max_tracking_loss_frames frames in a row that are starved (fewer than min_tracked_observations
// observations of the window's landmarks) or inconsistent (more than max_inconsistent_share of the
// checked observations beyond inconsistent_px); a frame that is neither resets the count; the
// first frame never counts.

#include <gtest/gtest.h>

#include "core/pipeline/tracking_monitor.h"

namespace marglab {
namespace {

// The rule's settings the tests state explicitly (not the defaults); `frames` lost in a row end a run.
FailureSettings lossConfig(int frames) {
  FailureSettings config;
  config.min_tracked_observations = 10;
  config.max_tracking_loss_frames = frames;
  config.inconsistent_px = 5;
  config.max_inconsistent_share = 0.3;
  return config;
}

FrameResult withConnected(int n) {
  FrameResult result;
  result.n_connected = n;
  return result;
}

TEST(TrackingMonitor, FailsAfterTheConfiguredRunOfStarvedFrames) {
  TrackingMonitor monitor(lossConfig(3));
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

FrameResult withChecked(int connected, int checked, int inconsistent) {
  FrameResult result = withConnected(connected);
  result.n_checked = checked;
  result.n_inconsistent = inconsistent;
  return result;
}

TEST(TrackingMonitor, FailsAfterTheConfiguredRunOfInconsistentFrames) {
  TrackingMonitor monitor(lossConfig(3));
  EXPECT_EQ(monitor.update(0, withChecked(0, 0, 0)), "");
  EXPECT_EQ(monitor.update(1, withChecked(200, 100, 31)), "");
  EXPECT_EQ(monitor.update(2, withChecked(200, 100, 31)), "");
  EXPECT_EQ(monitor.update(3, withChecked(200, 100, 30)), "");  // at the bound: consistent, resets
  EXPECT_EQ(monitor.update(4, withChecked(200, 100, 90)), "");
  EXPECT_EQ(monitor.update(5, withChecked(5, 0, 0)),
            "");  // starved: the run of lost frames goes on
  const std::string reason = monitor.update(6, withChecked(200, 120, 60));
  EXPECT_NE(reason.find("tracking lost: 3 frame(s) in a row in which more than 30 % of the "
                        "observations of the window's landmarks lie farther than 5 px"),
            std::string::npos)
      << reason;
  EXPECT_NE(reason.find("(this frame: 60 of 120)"), std::string::npos) << reason;
}

// Too few checked observations say nothing about consistency (one bad track of two is 50 %).
TEST(TrackingMonitor, FewCheckedObservationsAreNotJudged) {
  TrackingMonitor monitor(lossConfig(1));
  EXPECT_EQ(monitor.update(1, withChecked(50, 9, 9)), "");
  EXPECT_NE(monitor.update(2, withChecked(50, 10, 9)), "");
}

TEST(TrackingMonitor, FullShareTurnsTheConsistencyRuleOff) {
  FailureSettings config;
  config.max_tracking_loss_frames = 1;
  config.max_inconsistent_share = 1;
  TrackingMonitor monitor(config);
  for (int k = 0; k < 5; ++k) EXPECT_EQ(monitor.update(k, withChecked(50, 50, 50)), "");
}

TEST(TrackingMonitor, ZeroMinimumNeverFails) {
  FailureSettings config;
  config.min_tracked_observations = 0;
  config.max_tracking_loss_frames = 1;
  TrackingMonitor monitor(config);
  for (int k = 0; k < 10; ++k) EXPECT_EQ(monitor.update(k, withConnected(0)), "");  // none checked
}

}  // namespace
}  // namespace marglab
