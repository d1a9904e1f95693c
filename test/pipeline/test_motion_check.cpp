// The motion-consistency check (core/pipeline/motion_check.h) on synthetic positions: constant
// velocity and steady acceleration pass; a frame out of order fails at that frame with the ratio
// worked out by hand; a standing platform's jitter stays under the floor; 0 turns it off.

#include "core/pipeline/motion_check.h"

#include <gtest/gtest.h>

#include <string>

namespace marglab {
namespace {

constexpr std::int64_t kDtNs = 100'000'000;  // 10 Hz, as KITTI

// Feeds x positions (along the x axis, one frame per 0.1 s); the first frame that fails, or -1.
int firstFailure(const std::vector<double>& x, const FailureSettings& failure = {},
                 std::string* reason = nullptr) {
  MotionCheck check(failure);
  for (size_t k = 0; k < x.size(); ++k) {
    const std::string r = check.update(static_cast<int>(k), static_cast<std::int64_t>(k) * kDtNs,
                                       Eigen::Vector3d(x[k], 0, 0));
    if (!r.empty()) {
      if (reason != nullptr) *reason = r;
      return static_cast<int>(k);
    }
  }
  return -1;
}

TEST(MotionCheck, SmoothMotionPasses) {
  std::vector<double> constant, braking;
  for (int k = 0; k < 40; ++k) {
    constant.push_back(1.2 * k);
    braking.push_back(1.2 * k - 0.01 * k * k);  // 2 m/s², to a stop at k = 60
  }
  EXPECT_EQ(firstFailure(constant), -1);
  EXPECT_EQ(firstFailure(braking), -1);
}

TEST(MotionCheck, AFrameOutOfOrderFailsThere) {
  std::vector<double> x;
  for (int k = 0; k < 20; ++k) x.push_back(1.0 * k);
  std::swap(x[12], x[14]);  // 0 … 11, 14, 13, 12, 15
  // Frame 12: predicted 12, at 14: 2 m off, recent motion 1 m per frame → ratio 2, under 3.
  // Frame 13: predicted 14 + 3 = 17, at 13: 4 m off, recent median step 1 m → ratio 4.
  std::string reason;
  EXPECT_EQ(firstFailure(x, {}, &reason), 13);
  EXPECT_NE(reason.find("lies 4 m from the constant-velocity prediction, 4.0 times the recent "
                        "motion of 1 m per frame"),
            std::string::npos)
      << reason;
  FailureSettings off;
  off.max_motion_jump = 0;
  EXPECT_EQ(firstFailure(x, off), -1);
  FailureSettings loose;
  loose.max_motion_jump = 4.5;
  EXPECT_EQ(firstFailure(x, loose), -1);
}

TEST(MotionCheck, StandingJitterStaysUnderTheFloor) {
  std::vector<double> x;
  for (int k = 0; k < 40; ++k) x.push_back(k % 2 == 0 ? 0.0 : 0.004);  // ±4 mm, 5 cm floor
  EXPECT_EQ(firstFailure(x), -1);
  FailureSettings fine;
  fine.motion_floor_m = 0.001;  // jitter of 8 mm against 4 mm steps: ratio 2 … then 3
  x[20] = 0.02;
  EXPECT_GE(firstFailure(x, fine), 20);
}

}  // namespace
}  // namespace marglab
