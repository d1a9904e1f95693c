// The affine patch tracker (core/frontend/affine_patch_tracker.h) on a synthetic smooth texture
// and its exact affine warp (the second image rendered from the same analytic function, no
// resampling): it recovers the known point and 2×2 map, including a 1.25× forward-driving zoom
// that translation-only LK cannot follow, and reports failure on a flat image.

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "core/frontend/affine_patch_tracker.h"

namespace marglab {
namespace {

// A smooth, textured intensity in [30, 230] (sums of sines: corners everywhere at ~8 px scale).
double texture(double u, double v) {
  return 130 + 35 * std::sin(0.41 * u + 0.13 * v) + 35 * std::sin(0.07 * u - 0.37 * v + 1.0) +
         30 * std::sin(0.23 * u + 0.29 * v + 2.0);
}

// I_to(y) = gain · texture(A⁻¹ (y − x_to) + x_from): the warp W(u) = x_to + A u maps the patch
// around x_from onto it exactly.
cv::Mat render(const Eigen::Matrix2d& A, const Eigen::Vector2d& x_from, const Eigen::Vector2d& x_to,
               double gain) {
  cv::Mat image(200, 240, CV_8U);
  const Eigen::Matrix2d A_inv = A.inverse();
  for (int v = 0; v < image.rows; ++v) {
    for (int u = 0; u < image.cols; ++u) {
      const Eigen::Vector2d p = A_inv * (Eigen::Vector2d(u, v) - x_to) + x_from;
      image.at<uchar>(v, u) = cv::saturate_cast<uchar>(gain * texture(p.x(), p.y()));
    }
  }
  return image;
}

std::vector<cv::Mat> pyramid(const cv::Mat& image, int levels) {
  std::vector<cv::Mat> out;
  cv::buildPyramid(image, out, levels - 1);
  return out;
}

TEST(AffinePatchTracker, RecoversKnownZoomRotationAndShift) {
  const Eigen::Vector2d x_from(110, 95), x_to(116.7, 99.3);
  const double angle = 0.08;
  Eigen::Matrix2d A;
  A << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  A *= 1.25;
  A(0, 1) += 0.04;  // a little shear: the full affine model
  const cv::Mat from = render(Eigen::Matrix2d::Identity(), x_from, x_from, 1.0);
  const cv::Mat to = render(A, x_from, x_to, 0.9);  // and a gain change
  AffinePatch start;
  start.x = x_to + Eigen::Vector2d(2.0, -1.5);  // a prediction a few pixels off
  start.A = 1.2 * Eigen::Matrix2d::Identity();  // the predicted zoom, roughly
  AffinePatch result;
  ASSERT_TRUE(trackAffinePatch(pyramid(from, 2), pyramid(to, 2), x_from, start, PatchWarp::kAffine,
                               7, 2, 30, &result));
  EXPECT_LT((result.x - x_to).norm(), 0.05);
  EXPECT_LT((result.A - A).cwiseAbs().maxCoeff(), 0.02);
  EXPECT_GT(result.ncc, 0.99);
}

// kShift: the zoom is given (the front-end's predicted scale) and only the point is estimated.
TEST(AffinePatchTracker, ShiftUnderAKnownZoomRecoversThePoint) {
  const Eigen::Vector2d x_from(110, 95), x_to(118.4, 97.9);
  const Eigen::Matrix2d A = 1.3 * Eigen::Matrix2d::Identity();
  const cv::Mat from = render(Eigen::Matrix2d::Identity(), x_from, x_from, 1.0);
  const cv::Mat to = render(A, x_from, x_to, 1.1);
  AffinePatch start;
  start.x = x_to + Eigen::Vector2d(-3.0, 2.0);
  start.A = A;
  AffinePatch result;
  ASSERT_TRUE(trackAffinePatch(pyramid(from, 3), pyramid(to, 3), x_from, start, PatchWarp::kShift,
                               5, 3, 30, &result));
  EXPECT_LT((result.x - x_to).norm(), 0.02);
  EXPECT_EQ(result.A, A);
  EXPECT_GT(result.ncc, 0.99);
}

TEST(AffinePatchTracker, IdentityWarpStaysPut) {
  const Eigen::Vector2d x(120, 100);
  const cv::Mat image = render(Eigen::Matrix2d::Identity(), x, x, 1.0);
  AffinePatch start;
  start.x = x;
  AffinePatch result;
  ASSERT_TRUE(trackAffinePatch(pyramid(image, 1), pyramid(image, 1), x, start, PatchWarp::kAffine,
                               5, 1, 10, &result));
  EXPECT_LT((result.x - x).norm(), 1e-6);
  EXPECT_LT((result.A - Eigen::Matrix2d::Identity()).norm(), 1e-6);
  EXPECT_NEAR(result.ncc, 1.0, 1e-9);
}

TEST(AffinePatchTracker, FlatImageFails) {
  const cv::Mat flat(100, 100, CV_8U, cv::Scalar(128));
  AffinePatch start;
  start.x = Eigen::Vector2d(50, 50);
  AffinePatch result;
  EXPECT_FALSE(trackAffinePatch(pyramid(flat, 1), pyramid(flat, 1), start.x, start,
                                PatchWarp::kAffine, 5, 1, 10, &result));
}

TEST(AffinePatchTracker, PatchLeavingTheImageFails) {
  const Eigen::Vector2d x(120, 100);
  const cv::Mat image = render(Eigen::Matrix2d::Identity(), x, x, 1.0);
  AffinePatch start;
  start.x = Eigen::Vector2d(2, 100);  // the radius-5 patch reaches past the left edge
  AffinePatch result;
  EXPECT_FALSE(trackAffinePatch(pyramid(image, 1), pyramid(image, 1), x, start, PatchWarp::kShift,
                                5, 1, 10, &result));
}

}  // namespace
}  // namespace marglab
