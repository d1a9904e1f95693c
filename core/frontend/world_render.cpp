#include "core/frontend/world_render.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/sim/feature_tracker.h"
#include "core/sim/wall_buffer.h"

namespace marglab {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kSpriteSigmaPx = 1.8;
constexpr int kSpriteHalfPx = 10;  // the sprite covers [floor(c) − 9, floor(c) + 10]
constexpr std::size_t kSwappedKey = std::size_t{1} << 40;
constexpr double kConeMarginRad = 0.02;

cv::Mat backgroundImage(int width, int height) {
  cv::Mat image(height, width, CV_64FC1);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      image.at<double>(v, u) = 128.0 + 20.0 * std::sin(0.004 * u + 0.003 * v);
    }
  }
  return image;
}

bool inDrawnArea(const Eigen::Vector2d& c, int width, int height) {
  // Sprites partly outside the image are drawn too: points leave the view gradually.
  return !(c.x() < -kSpriteHalfPx || c.y() < -kSpriteHalfPx || c.x() > width + kSpriteHalfPx - 1 ||
           c.y() > height + kSpriteHalfPx - 1);
}

// α of the header: the largest angle to the optical axis of a ray whose raw pixel lies on the
// border of the drawn area, plus a margin; π/2 when a border pixel cannot be undistorted.
double maxRayAngle(const CameraModel<double>& cam) {
  const double u0 = -kSpriteHalfPx, v0 = -kSpriteHalfPx;
  const double u1 = cam.width + kSpriteHalfPx - 1, v1 = cam.height + kSpriteHalfPx - 1;
  std::vector<Eigen::Vector2d> border;
  constexpr double kStepPx = 4.0;
  for (double u = u0; u < u1 + kStepPx; u += kStepPx) {
    border.emplace_back(std::min(u, u1), v0);
    border.emplace_back(std::min(u, u1), v1);
  }
  for (double v = v0; v < v1 + kStepPx; v += kStepPx) {
    border.emplace_back(u0, std::min(v, v1));
    border.emplace_back(u1, std::min(v, v1));
  }
  double angle = 0;
  for (const Eigen::Vector2d& raw : border) {
    Eigen::Vector2d uv;
    if (!cam.undistortPixel(raw, &uv)) return kPi / 2;
    const double r = std::hypot((uv.x() - cam.cx) / cam.fx, (uv.y() - cam.cy) / cam.fy);
    angle = std::max(angle, std::atan(r));
  }
  return std::min(angle + kConeMarginRad, kPi / 2);
}

void drawSprite(const Sprite& s, const Eigen::Vector2d& c, cv::Mat* image) {
  const int u0 = static_cast<int>(std::floor(c.x())) - (kSpriteHalfPx - 1),
            v0 = static_cast<int>(std::floor(c.y())) - (kSpriteHalfPx - 1);
  for (int v = std::max(v0, 0); v <= std::min(v0 + 2 * kSpriteHalfPx - 1, image->rows - 1); ++v) {
    for (int u = std::max(u0, 0); u <= std::min(u0 + 2 * kSpriteHalfPx - 1, image->cols - 1); ++u) {
      double value = 0;
      for (int i = 0; i < 4; ++i) {
        const double du = u - c.x() - s.du[i], dv = v - c.y() - s.dv[i];
        value +=
            s.amplitude[i] * std::exp(-(du * du + dv * dv) / (2 * kSpriteSigmaPx * kSpriteSigmaPx));
      }
      image->at<double>(v, u) += value;
    }
  }
}

}  // namespace

RenderOptions defaultRenderOptions(DatasetKind kind) {
  RenderOptions o;
  if (kind == DatasetKind::kKitti) {
    o.max_depth = 250.0;
    o.thinning_depth = 20.0;
  }
  return o;
}

WorldOptions renderWorldOptions(DatasetKind kind) {
  WorldOptions o = defaultWorldOptions(kind);
  if (o.kind == WorldKind::kIndoor) {
    o.surface_density = kind == DatasetKind::kTumvi ? 3.0 : 6.0;
    o.clutter_point_density = 0.2;
  }
  return o;
}

Sprite spriteOf(std::size_t key) {
  SimRandom random(SimRandom::subSeed(0x5eed, key));
  Sprite s;
  for (int i = 0; i < 4; ++i) {
    s.amplitude[i] = (random.bernoulli(0.5) ? 1.0 : -1.0) * random.uniform(40.0, 90.0);
    s.du[i] = random.uniform(-3.0, 3.0);
    s.dv[i] = random.uniform(-3.0, 3.0);
  }
  return s;
}

WorldRenderer::WorldRenderer(const World& world, const StereoCalib& calib,
                             const RenderOptions& options)
    : world_(world), options_(options) {
  const CameraCalib* cams[2] = {&calib.cam0, &calib.cam1};
  for (int i = 0; i < 2; ++i) {
    view_[i].calib = *cams[i];
    view_[i].model = cameraModelFromCalib<double>(*cams[i], "render");
    view_[i].background = backgroundImage(cams[i]->width, cams[i]->height);
    view_[i].max_ray_angle = maxRayAngle(view_[i].model);
  }
}

int WorldRenderer::vanishFrame(std::size_t l) const {
  SimRandom random(SimRandom::subSeed(0xfade, l));
  int frame = 1;
  while (!random.bernoulli(options_.vanish_probability) && frame < 1000000) ++frame;
  return frame;
}

RenderedFrame WorldRenderer::render(const TrajectorySample& body, int frame_index) const {
  RenderedFrame out;
  out.left = renderCamera(body, 0, frame_index, &out.centre0);
  out.right = renderCamera(body, 1, frame_index, &out.centre1);
  return out;
}

Eigen::Vector2d WorldRenderer::spriteCentre(int camera, const Eigen::Vector3d& p_c) const {
  const CameraModel<double>& cam = view_[camera].model;
  const Eigen::Vector2d pinhole(cam.fx * p_c.x() / p_c.z() + cam.cx,
                                cam.fy * p_c.y() / p_c.z() + cam.cy);
  return cam.distortPixel(pinhole);
}

bool WorldRenderer::thinnedOut(std::size_t l, double z) const {
  if (!(options_.thinning_depth > 0) || z <= options_.thinning_depth ||
      world_.normals_w[l].isZero()) {
    return false;
  }
  const double keep = std::pow(options_.thinning_depth / z, 3);
  return static_cast<double>(SimRandom::subSeed(0x7417, l) >> 11) * 0x1.0p-53 >= keep;
}

bool WorldRenderer::chunkMayBeVisible(const WorldChunk& chunk, const Eigen::Matrix3d& R_c_w,
                                      const Eigen::Vector3d& p_w_c, const View& view) const {
  const Eigen::Vector3d c = R_c_w * (chunk.centre - p_w_c);
  const double r = chunk.radius;
  if (c.z() + r < options_.min_depth || c.z() - r > options_.max_depth) return false;
  const double d = c.norm();
  if (view.max_ray_angle >= kPi / 2 || d <= r) return true;
  // The sphere meets the cone when the angle of its centre, less its angular radius, is ≤ α.
  const double angle = std::acos(std::clamp(c.z() / d, -1.0, 1.0));
  return angle - std::asin(r / d) <= view.max_ray_angle;
}

cv::Mat WorldRenderer::renderCamera(
    const TrajectorySample& body, int camera, int frame_index,
    std::unordered_map<std::size_t, Eigen::Vector2d>* centres) const {
  const View& view = view_[camera];
  Eigen::Matrix3d R_w_c;
  Eigen::Vector3d p_w_c;
  cameraPose(body, view.calib, &R_w_c, &p_w_c);
  const Eigen::Matrix3d R_c_w = R_w_c.transpose();
  const WallBuffer walls(world_, R_c_w, p_w_c, view.calib, options_.max_depth);
  cv::Mat image = view.background.clone();
  for (const WorldChunk& chunk : world_.chunks) {
    if (culling_ && !chunkMayBeVisible(chunk, R_c_w, p_w_c, view)) continue;
    for (std::size_t l = chunk.begin; l < chunk.end; ++l) {
      const Eigen::Vector3d p_c = R_w_c.transpose() * (world_.points_w[l] - p_w_c);
      if (p_c.z() < options_.min_depth || p_c.z() > options_.max_depth ||
          !world_.facing(l, p_w_c) || thinnedOut(l, p_c.z())) {
        continue;
      }
      const Eigen::Vector2d c = spriteCentre(camera, p_c);
      if (!inDrawnArea(c, view.calib.width, view.calib.height)) continue;
      const CameraCalib& k = view.calib;
      if (walls.hidden(p_c, {k.fx * p_c.x() / p_c.z() + k.cx, k.fy * p_c.y() / p_c.z() + k.cy})) {
        continue;
      }
      (*centres)[l] = c;
      drawSprite(spriteOf(frame_index >= vanishFrame(l) ? l + kSwappedKey : l), c, &image);
    }
  }
  cv::Mat grey;
  image.convertTo(grey, CV_8UC1);  // rounds and saturates
  return grey;
}

}  // namespace marglab
