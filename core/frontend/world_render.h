#pragma once
// Renders the simulated world (core/sim/world.h) into stereo images with known pixel truth,
// through a dataset's real camera model (camera_model.h: radial-tangential, Kannala–Brandt
// fisheye, rectified pinhole). `marglab datasets render` writes such images as a dataset folder
// (rendered_folder.h); the front-end tests score tracking against the truth.
//
// What is drawn. Each visible world point l is drawn as a screen-space sprite centred at its true
// raw pixel c = d(π(p_c)) (π the pinhole projection of the calibration, d its distortion):
//   I(x) += Σ_i a_i exp(−‖x − c − o_i‖² / (2σ²)),  4 blobs, σ = 1.8 px, o_i ∈ [−3, 3]² px,
//   a_i = ±[40, 90] grey levels, all drawn from a hash of l (spriteOf),
// evaluated at the pixels of a 20×20 px square around c, on a smooth background
// 128 + 20 sin(0.004 u + 0.003 v) (a low-frequency ramp, no corners); the sum is rounded and
// saturated to 8 bits. Sprites add where they overlap, in the order of World::points_w.
//
// Why the truth is exact. The sprite is a smooth function evaluated at the pixel centres, so its
// position is exact to sub-pixel level, and it looks the same in every frame and in both cameras:
// a keypoint detected at an offset δ from c stays at c + δ in every image where the sprite is
// drawn. That is the truth a test compares with (the offset cancels, only tracking error remains).
// The sprite does not shrink with distance nor bend with the distortion: only its centre follows
// the camera model, which is what a front-end's keypoint follows.
//
// Swapping. From frame vanishFrame(l) on (geometric with vanish_probability per frame), the point
// is drawn with another texture (an occluding object now covers it); the keypoint on the old
// texture has no true position any more, so a track that jumps to a wrong pixel there is an
// outlier (what the front-end's checks must catch). The sprite centre, the point's true pixel,
// does not change.
//
// Visibility. A point is drawn in a camera when its depth z is in [min_depth, max_depth], it faces
// the camera (World::facing), no world wall hides it (wall_buffer.h; street worlds), it is not
// thinned out (below) and its sprite overlaps the image (centre within 10 px of it). Rays at 90°
// or more from the optical axis (the corners of a fisheye image) show the background only.
//
// Thinning. Sprites keep their size at any distance, while a surface seen at depth z packs its
// points ∝ z³ more densely into the image (∝ z² by perspective, ∝ z once more for a facade seen
// at a grazing angle down a street): beyond a few tens of metres they would pile up into one
// blur. A surface point (non-zero normal) beyond thinning_depth z_t is therefore drawn only when
// h_l < (z_t / z)³, h_l ∈ [0, 1) a hash of l — a fixed subset, so the image density of far
// surfaces stays about that at z_t; as the camera approaches a point it may appear, never
// vanish. Free points (zero normal: clutter, KITTI's far hills) are not thinned.
//
// Speed. Only the world's chunks that can hold a visible point are visited: those whose bounding
// sphere meets the depth slab and the cone of half-angle α around the optical axis, α = the
// largest angle of a ray whose raw pixel lies in the drawn area (its border undistorted; no cone
// where undistortion fails there, e.g. a fisheye whose corners look sideways) plus 0.02 rad. This
// assumes the distortion moves rays outwards monotonically inside the image, as the shipped
// calibrations do (RenderedTruth in test/frontend checks that culling drops no drawn point).
//
// Deterministic: every random quantity is a hash of the landmark index.

#include <Eigen/Core>

#include <cstddef>
#include <opencv2/core.hpp>
#include <unordered_map>
#include <vector>

#include "core/data/types.h"
#include "core/frontend/camera_model.h"
#include "core/sim/trajectory_spline.h"
#include "core/sim/world.h"

namespace marglab {

struct RenderOptions {
  double min_depth = 0.3;            // [m]
  double max_depth = 15.0;           // [m]
  double vanish_probability = 0.02;  // texture swaps per landmark and frame
  double thinning_depth = 0;         // [m] z_t of the header's thinning; 0: none
};
// Indoor: the defaults; KITTI: depth up to 250 m (the simulator's, feature_tracker.h), surface
// points thinned beyond 20 m.
RenderOptions defaultRenderOptions(DatasetKind kind);

// The world to render: the simulator's (world.h) with sparser indoor surfaces (EuRoC 6 points/m²,
// TUM-VI 3 — its fisheye sees about twice the solid angle —, 0.2 free points/m³), so that
// ~150–300 sprites are in view and few overlap.
WorldOptions renderWorldOptions(DatasetKind kind);

struct Sprite {
  double amplitude[4];
  double du[4], dv[4];
};
// The sprite of a texture key (a landmark index; a swapped landmark l uses l + 2⁴⁰).
Sprite spriteOf(std::size_t key);

struct RenderedFrame {
  cv::Mat left, right;  // 8-bit grey, the calibration's size
  // True raw sprite centres of the points drawn in this frame, per camera.
  std::unordered_map<std::size_t, Eigen::Vector2d> centre0, centre1;
};

class WorldRenderer {
 public:
  // Throws InputError (naming "render") for a camera model it cannot apply.
  WorldRenderer(const World& world, const StereoCalib& calib, const RenderOptions& options);

  // The frame at which landmark l is first drawn with its swapped texture.
  int vanishFrame(std::size_t l) const;

  RenderedFrame render(const TrajectorySample& body, int frame_index) const;

  // The sprite centre of a camera-frame point in camera i (0 left, 1 right): d(π(p_c)).
  Eigen::Vector2d spriteCentre(int camera, const Eigen::Vector3d& p_c) const;

  // Without the chunk culling (every point tested): for the test that culling loses nothing.
  void setCulling(bool enabled) { culling_ = enabled; }

 private:
  struct View {
    CameraCalib calib;
    CameraModel<double> model;
    cv::Mat background;        // CV_64FC1
    double max_ray_angle = 0;  // α [rad]; ≥ π/2: no cone test
  };
  cv::Mat renderCamera(const TrajectorySample& body, int camera, int frame_index,
                       std::unordered_map<std::size_t, Eigen::Vector2d>* centres) const;
  bool thinnedOut(std::size_t l, double z) const;
  bool chunkMayBeVisible(const WorldChunk& chunk, const Eigen::Matrix3d& R_c_w,
                         const Eigen::Vector3d& p_w_c, const View& view) const;

  const World& world_;
  RenderOptions options_;
  View view_[2];
  bool culling_ = true;
};

}  // namespace marglab
