// The front-end on rendered frames of each camera-model family at its real frame rate, as
// `marglab datasets render` renders them (rendered_folder.h: planRendering): EuRoC V1_03_difficult
// in flight (radial-tangential, 20 Hz), TUM-VI room1 (Kannala–Brandt fisheye, 20 Hz), KITTI 00
// (rectified pinhole, 10 Hz driving). Scored against the true pixels (rendered_world.h) with
// issue #29's targets: tracking error median ≤ 0.1 px and 95th percentile ≤ 0.5 px, and ≥ 80 %
// of the features continued from frame to frame (median over the frames).

#include <gtest/gtest.h>

#include <cmath>

#include "core/frontend/rendered_folder.h"
#include "frontend/rendered_world.h"

namespace marglab {
namespace {

constexpr int kFrames = 40;

// Issue #29's targets. Before the motion prediction and the patch check, TUM-VI's 95th percentile
// (0.60 px) and KITTI's share continued (59 %) missed them.
void expectMedian(const test::Measured& m) {
  ASSERT_GT(m.raw_error.size(), 500u);
  EXPECT_LE(test::percentile(m.raw_error, 0.5), 0.1);
}
void expectP95(const test::Measured& m) { EXPECT_LE(test::percentile(m.raw_error, 0.95), 0.5); }
void expectContinued(const test::Measured& m) {
  EXPECT_GE(test::percentile(m.continued, 0.5), 0.8);
}
void expectOutliersRemoved(const test::Measured& m) {
  ASSERT_GT(m.wrong_forward, 20);  // the texture swaps do produce wrong forward steps
  EXPECT_GE(static_cast<double>(m.wrong_removed) / m.wrong_forward, 0.9);
}

// The tracking error is scored in the raw image, where the tracker works and the truth is a
// pixel; the pinhole-image error (printed too) magnifies it towards a fisheye's rim.
test::Measured trackFamily(const char* dataset, double start_s) {
  const RenderPlan plan = planRendering(dataset, kFrames, start_s, 0);
  std::vector<RenderedFrame> images;
  std::vector<TrackFrame> frames;
  return test::trackRendered(
      dataset, {&plan.sequence, plan.spline.get(), &plan.world, plan.render, plan.t_ns}, &images,
      &frames);
}

const test::Measured& euroc() {
  static const test::Measured m = trackFamily("euroc/V1_03_difficult", 8.0);
  return m;
}
const test::Measured& tumvi() {
  static const test::Measured m = trackFamily("tumvi/room1", 10.0);
  return m;
}
const test::Measured& kitti() {
  static const test::Measured m = trackFamily("kitti/00", 0.0);
  return m;
}

TEST(RenderedFamilies, EurocV103InFlightMeetsTargets) {
  expectMedian(euroc());
  expectP95(euroc());
  expectContinued(euroc());
  expectOutliersRemoved(euroc());
}

TEST(RenderedFamilies, TumviRoom1FisheyeMeetsTargets) {
  expectMedian(tumvi());
  expectP95(tumvi());
  expectContinued(tumvi());
  expectOutliersRemoved(tumvi());
}

TEST(RenderedFamilies, Kitti00DrivingMeetsTargets) {
  expectMedian(kitti());
  expectP95(kitti());
  expectContinued(kitti());
  expectOutliersRemoved(kitti());
}

// The front-end's stereo disparities carry no bias of their own: on the real KITTI 06 frames they
// are ~0.22 px below motion stereo (results/real_kitti06/README.md), a ~1 % longer trajectory, and
// that is the frames' rectification, not the tracker — which this checks against the true pixels.
// Bound: 0.02 px, a tenth of that bias (0.1 % of depth at 20 m); the median of ~2200 matches
// whose error is ~0.02 px is known to ~0.001 px (measured: −0.0004 px), so the bound tests a bias,
// not the noise; shifting every right keypoint by 0.05 px makes it fail.
TEST(RenderedFamilies, Kitti00StereoDisparityUnbiased) {
  const test::Measured& m = kitti();
  ASSERT_GT(m.disparity_error.size(), 1000u);
  EXPECT_LE(std::abs(test::percentile(m.disparity_error, 0.5)), 0.02);
}

}  // namespace
}  // namespace marglab
