#pragma once
// Camera models of the three datasets, and the undistortion of keypoints into the pinhole image
// the estimator uses (core/geometry/camera.h: the same fx, fy, cx, cy, no distortion).
//
// A raw pixel (u_d, v_d) of the recorded image relates to normalized image coordinates
// x = (x, y) = (X/Z, Y/Z) of a camera-frame point through a distortion d: x ↦ x_d and the
// intrinsics:  (u_d, v_d) = (fx x_d + cx, fy y_d + cy).  The estimator's pinhole pixel is
// (u, v) = (fx x + cx, fy y + cy). Undistorting a keypoint = solving d(x) = x_d for x.
//
//   kNone (KITTI, rectified):  d(x) = x.
//   kRadTan (EuRoC, Kalibr "radtan", OpenCV's first 4 coefficients k1 k2 p1 p2):
//     r² = x² + y²,  ρ = 1 + k1 r² + k2 r⁴,
//     x_d = ρ x + 2 p1 x y + p2 (r² + 2x²),   y_d = ρ y + p1 (r² + 2y²) + 2 p2 x y.
//     ∂x_d/∂x = ρ + 2x ρ' x + 2 p1 y + 6 p2 x,   ∂x_d/∂y = 2y ρ' x + 2 p1 x + 2 p2 y,
//     ∂y_d/∂x = 2x ρ' y + 2 p1 x + 2 p2 y,         ∂y_d/∂y = ρ + 2y ρ' y + 6 p1 y + 2 p2 x,
//     with ρ' = ∂ρ/∂(r²) = k1 + 2 k2 r².
//     Inverse: Gauss–Newton on ‖d(x) − x_d‖² from x = x_d (the map is a small perturbation of
//     the identity inside the image, so a few steps converge quadratically).
//   kEquidistant (TUM-VI, Kalibr "equidistant" = Kannala–Brandt with 4 coefficients):
//     r = ‖x‖, θ = atan r (angle to the optical axis), θ_d = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸),
//     x_d = (θ_d / r) x  (x_d = x as r → 0, where θ_d/r → 1).
//     ∂x_d/∂x = s I + (s' / r) x xᵀ,  s = θ_d / r,  s' = ds/dr = (θ_d'(θ) θ'(r) r − θ_d) / r²,
//     θ'(r) = 1/(1 + r²),  θ_d'(θ) = 1 + 3k1 θ² + 5k2 θ⁴ + 7k3 θ⁶ + 9k4 θ⁸.
//     Inverse: the map is radial, so only θ is unknown: Newton on θ_d(θ) = ‖x_d‖, then
//     x = tan(θ) x_d / ‖x_d‖. Rays with θ ≥ max_theta (near 90°) have no pinhole image: refused.
// A point whose undistortion does not converge (outside the region where d is invertible) is
// refused (returns false): the front-end drops it rather than feed the estimator a wrong pixel.

#include <Eigen/Core>

#include <array>
#include <string>

#include "core/data/types.h"

namespace marglab {

enum class DistortionModel { kNone, kRadTan, kEquidistant };
const char* distortionModelName(DistortionModel model);  // "none", "radtan", "equidistant"

template <typename Scalar>
struct CameraModel {
  using Vec2 = Eigen::Matrix<Scalar, 2, 1>;
  using Mat2 = Eigen::Matrix<Scalar, 2, 2>;

  DistortionModel model = DistortionModel::kNone;
  Scalar fx = 1, fy = 1, cx = 0, cy = 0;
  std::array<Scalar, 4> k{};  // radtan: k1 k2 p1 p2; equidistant: k1 k2 k3 k4
  int width = 0, height = 0;

  // Normalized undistorted x → normalized distorted x_d, with ∂x_d/∂x when J is given.
  Vec2 distortNormalized(const Vec2& x, Mat2* J = nullptr) const;
  // Solves d(x) = x_d; false when it has no (converged) solution.
  bool undistortNormalized(const Vec2& x_d, Vec2* x) const;

  // Pinhole pixel (estimator image) → raw pixel of the recorded image.
  Vec2 distortPixel(const Vec2& uv) const;
  // Raw pixel → pinhole pixel; false when the point cannot be undistorted.
  bool undistortPixel(const Vec2& uv_d, Vec2* uv) const;
};

// The model of a dataset camera ("radtan", "equidistant", "none"); throws InputError naming
// `source` for a model it does not know or the wrong number of coefficients.
template <typename Scalar>
CameraModel<Scalar> cameraModelFromCalib(const CameraCalib& calib, const std::string& source);

}  // namespace marglab
