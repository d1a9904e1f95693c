#pragma once
// Pinhole camera and stereo rig (undistorted pinhole model; the simulator measures in it).
//
// Pixel convention: pixel centres at integer coordinates, (0, 0) the centre of the top-left
// pixel; x right, y down, z forward (optical axis).
//   project:    (u, v) = (fx x/z + cx, fy y/z + cy),   valid for z ≥ min_depth,
//               ∂(u,v)/∂p = [ fx/z  0     −fx x/z² ]
//                           [ 0     fy/z  −fy y/z² ]
//   unproject:  b = normalize((u − cx)/fx, (v − cy)/fy, 1)
//   inImage:    border ≤ u ≤ width − 1 − border and the same for v.
// min_depth defaults to √ε of the scalar (as Basalt's pinhole model): it only guards the
// division; projection is scale invariant, so it is also applied to ρ-scaled points
// (stereographic.h).
//
// StereoRig: cam0, cam1 with body-to-camera extrinsics T_i_c0, T_i_c1 (EuRoC's T_BS). For pure VO
// set T_i_c0 = identity and T_i_c1 = T_c0_c1. T_c0_c1() = T_i_c0⁻¹ T_i_c1.
// triangulate: midpoint of the common perpendicular of the two rays in cam0,
//   ray 0: s0 d0,  ray 1: t + s1 d1   (t = t_c0_c1, d1 = R_c0_c1 b1, |d0| = |d1| = 1),
//   least squares of s0 d0 − s1 d1 = t:  s0 = (d0·t − c e)/σ², s1 = (c d0·t − e)/σ²,
//   c = d0·d1, e = d1·t, σ² = |d0 × d1|² = 1 − c² (evaluated through the cross product, which
//   does not cancel at small parallax), p_c0 = ½ (s0 d0 + t + s1 d1).
// It fails (returns false, p untouched) when the baseline is below min_baseline, the parallax
// angle (asin |d0 × d1|) below min_parallax, or the point is not in front of both cameras
// (depth < each camera's min_depth). Noise-free rays give the exact point up to rounding,
// amplified by 1/σ (≈ depth/baseline).

#include <Eigen/Core>
#include <cmath>

#include "core/common/eigen_types.h"
#include "core/common/scalar.h"
#include "core/geometry/se3.h"

namespace marglab {

template <typename Scalar>
struct PinholeCamera {
  Scalar fx = Scalar(1);
  Scalar fy = Scalar(1);
  Scalar cx = Scalar(0);
  Scalar cy = Scalar(0);
  int width = 0;
  int height = 0;
  Scalar min_depth = NumericTraits<Scalar>::sqrtEpsilon();

  // Returns false (outputs untouched) if p_c.z() < min_depth.
  bool project(const Vec3<Scalar>& p_c, Vec<Scalar, 2>* uv,
               Mat<Scalar, 2, 3>* d_uv_d_p = nullptr) const {
    const Scalar z = p_c.z();
    if (!(z >= min_depth)) return false;
    const Scalar z_inv = Scalar(1) / z;
    const Scalar x_n = p_c.x() * z_inv;
    const Scalar y_n = p_c.y() * z_inv;
    *uv = Vec<Scalar, 2>(fx * x_n + cx, fy * y_n + cy);
    if (d_uv_d_p != nullptr) {
      (*d_uv_d_p) << fx * z_inv, Scalar(0), -fx * x_n * z_inv, Scalar(0), fy * z_inv,
          -fy * y_n * z_inv;
    }
    return true;
  }

  // Unit bearing through pixel uv.
  Vec3<Scalar> unproject(const Vec<Scalar, 2>& uv) const {
    return Vec3<Scalar>((uv.x() - cx) / fx, (uv.y() - cy) / fy, Scalar(1)).normalized();
  }

  bool inImage(const Vec<Scalar, 2>& uv, Scalar border = Scalar(0)) const {
    return uv.x() >= border && uv.y() >= border &&
           uv.x() <= static_cast<Scalar>(width - 1) - border &&
           uv.y() <= static_cast<Scalar>(height - 1) - border;
  }

  template <typename T>
  PinholeCamera<T> cast() const {
    return PinholeCamera<T>{T(fx), T(fy), T(cx), T(cy), width, height, T(min_depth)};
  }
};

template <typename Scalar>
struct TriangulationOptions {
  Scalar min_baseline = Scalar(0.05);  // metres (docs/design.md §3)
  Scalar min_parallax = Scalar(1e-3);  // radians between the two rays
};

template <typename Scalar>
struct StereoRig {
  PinholeCamera<Scalar> cam0;
  PinholeCamera<Scalar> cam1;
  SE3<Scalar> T_i_c0;
  SE3<Scalar> T_i_c1;

  SE3<Scalar> T_c0_c1() const { return T_i_c0.inverse() * T_i_c1; }

  // Midpoint triangulation of pixel uv0 in cam0 and uv1 in cam1; the point in cam0 on success.
  bool triangulate(const Vec<Scalar, 2>& uv0, const Vec<Scalar, 2>& uv1, Vec3<Scalar>* p_c0,
                   const TriangulationOptions<Scalar>& options = {}) const;

  template <typename T>
  StereoRig<T> cast() const {
    return StereoRig<T>{cam0.template cast<T>(), cam1.template cast<T>(), T_i_c0.template cast<T>(),
                        T_i_c1.template cast<T>()};
  }
};

}  // namespace marglab
