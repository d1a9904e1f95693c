#pragma once
// Renders the simulated world (core/sim/world.h) into stereo images with known truth, for the
// front-end accuracy test.
//
// Each visible world point l is drawn as a screen-space sprite centred at its true raw pixel
// c = d(π(p_c)) (π the pinhole projection of the calibration, d its distortion, camera_model.h):
//   I(x) += Σ_i a_i exp(−‖x − c − o_i‖² / (2σ²)),  4 blobs, σ = 1.8 px, o_i ∈ [−3, 3]² px,
//   a_i = ±[40, 90] grey levels, all drawn from a hash of l,
// on a smooth background (128 + a low-frequency ramp, no corners). The sprite is a smooth
// function evaluated at the pixel centres, so its position is exact to sub-pixel level, and it
// looks the same in every frame and in both cameras: a keypoint detected at an offset δ from c
// stays at c + δ in every image where the sprite is drawn. That is the truth the test compares
// with (the offset cancels, only tracking error remains).
// Swapping: from frame vanishFrame(l) on, the point is drawn with another texture (an occluding
// object now covers it); the keypoint on the old texture has no true position any more, so a
// track that jumps to a wrong pixel there is an outlier (what the forward–backward check must
// catch). The sprite centre, the point's true pixel, does not change. A point is visible when its
// depth is in [0.3, 15] m, it faces the camera (World::facing) and its sprite overlaps the image.

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <unordered_map>
#include <vector>

#include "core/data/types.h"
#include "core/frontend/camera_model.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/world.h"

namespace marglab::test {

struct Sprite {
  double amplitude[4];
  double du[4], dv[4];
};

inline Sprite spriteOf(std::size_t landmark) {
  SimRandom random(SimRandom::subSeed(0x5eed, landmark));
  Sprite s;
  for (int i = 0; i < 4; ++i) {
    s.amplitude[i] = (random.bernoulli(0.5) ? 1.0 : -1.0) * random.uniform(40.0, 90.0);
    s.du[i] = random.uniform(-3.0, 3.0);
    s.dv[i] = random.uniform(-3.0, 3.0);
  }
  return s;
}

struct RenderedFrame {
  cv::Mat left, right;
  // True raw sprite centres of the points drawn in this frame, per camera.
  std::unordered_map<std::size_t, Eigen::Vector2d> centre0, centre1;
};

class WorldRenderer {
 public:
  WorldRenderer(const World& world, const StereoCalib& calib, double vanish_probability)
      : world_(world), calib_(calib), vanish_probability_(vanish_probability) {
    cam_[0] = cameraModelFromCalib<double>(calib.cam0, "test");
    cam_[1] = cameraModelFromCalib<double>(calib.cam1, "test");
  }

  // The frame at which landmark l stops being drawn (a fixed function of l).
  int vanishFrame(std::size_t l) const {
    SimRandom random(SimRandom::subSeed(0xfade, l));
    int frame = 1;
    while (!random.bernoulli(vanish_probability_) && frame < 1000000) ++frame;
    return frame;
  }

  RenderedFrame render(const TrajectorySample& body, int frame_index) const {
    RenderedFrame out;
    out.left = renderCamera(body, calib_.cam0, cam_[0], frame_index, &out.centre0);
    out.right = renderCamera(body, calib_.cam1, cam_[1], frame_index, &out.centre1);
    return out;
  }

 private:
  cv::Mat renderCamera(const TrajectorySample& body, const CameraCalib& calib,
                       const CameraModel<double>& cam, int frame_index,
                       std::unordered_map<std::size_t, Eigen::Vector2d>* centres) const {
    Eigen::Matrix3d R_w_c;
    Eigen::Vector3d p_w_c;
    cameraPose(body, calib, &R_w_c, &p_w_c);
    cv::Mat image(calib.height, calib.width, CV_64FC1);
    for (int v = 0; v < calib.height; ++v) {
      for (int u = 0; u < calib.width; ++u) {
        image.at<double>(v, u) = 128.0 + 20.0 * std::sin(0.004 * u + 0.003 * v);
      }
    }
    // Far to near, so that nearer sprites are drawn last (they add; overlaps are rare).
    for (std::size_t l = 0; l < world_.points_w.size(); ++l) {
      const Eigen::Vector3d p_c = R_w_c.transpose() * (world_.points_w[l] - p_w_c);
      if (p_c.z() < 0.3 || p_c.z() > 15.0 || !world_.facing(l, p_w_c)) continue;
      const Eigen::Vector2d pinhole(cam.fx * p_c.x() / p_c.z() + cam.cx,
                                    cam.fy * p_c.y() / p_c.z() + cam.cy);
      const Eigen::Vector2d c = cam.distortPixel(pinhole);
      // Sprites partly outside the image are drawn too: points leave the view gradually.
      if (c.x() < -10 || c.y() < -10 || c.x() > calib.width + 9 || c.y() > calib.height + 9)
        continue;
      const bool swapped = frame_index >= vanishFrame(l);
      (*centres)[l] = c;
      drawSprite(spriteOf(swapped ? l + (std::size_t{1} << 40) : l), c, &image);
    }
    cv::Mat grey;
    image.convertTo(grey, CV_8UC1);  // rounds and saturates
    return grey;
  }

  static void drawSprite(const Sprite& s, const Eigen::Vector2d& c, cv::Mat* image) {
    constexpr double kSigma = 1.8;
    const int u0 = static_cast<int>(std::floor(c.x())) - 9,
              v0 = static_cast<int>(std::floor(c.y())) - 9;
    for (int v = std::max(v0, 0); v <= std::min(v0 + 19, image->rows - 1); ++v) {
      for (int u = std::max(u0, 0); u <= std::min(u0 + 19, image->cols - 1); ++u) {
        double value = 0;
        for (int i = 0; i < 4; ++i) {
          const double du = u - c.x() - s.du[i], dv = v - c.y() - s.dv[i];
          value += s.amplitude[i] * std::exp(-(du * du + dv * dv) / (2 * kSigma * kSigma));
        }
        image->at<double>(v, u) += value;
      }
    }
  }

  const World& world_;
  StereoCalib calib_;
  CameraModel<double> cam_[2];
  double vanish_probability_;
};

}  // namespace marglab::test
