#pragma once
// Occlusion by the world's vertical walls (World::walls), as seen by one camera: a per-column
// depth buffer. Used by the track simulator (feature_tracker.h) and the image renderer
// (core/frontend/world_render.h), so that both hide the same points.
//
// Walls are taken as vertical in the camera's x–z plane (KITTI cameras are level). Column c of
// the pinhole image looks along the ray (t_c, 1) z with t_c = (c − cx)/fx; a wall with ends A, B
// (camera x, z) meets it at
//   z = cross(A, D) / cross((t_c, 1), D),  D = B − A,  cross(u, v) = u_x v_z − u_z v_x.
// Each column keeps the nearest wall; a point (x, z) in column round(u) is hidden when it lies
// behind that wall's line at the point's own ray t = x/z (evaluated exactly, so that points on
// the wall itself are not hidden by the column discretization). Walls further than max_depth
// (plus their length) are skipped.

#include <Eigen/Core>
#include <vector>

#include "core/data/types.h"
#include "core/sim/world.h"

namespace marglab {

class WallBuffer {
 public:
  // The camera at p_w_c with world-to-camera rotation R_c_w; its pinhole part and width.
  WallBuffer(const World& world, const Eigen::Matrix3d& R_c_w, const Eigen::Vector3d& p_w_c,
             const CameraCalib& calib, double max_depth);

  // Whether the camera-frame point p_c with pinhole pixel uv lies behind a wall.
  bool hidden(const Eigen::Vector3d& p_c, const Eigen::Vector2d& uv) const;

 private:
  struct Line {
    Eigen::Vector2d A, D;
  };
  static double lineDepth(const Line& line, double t);
  std::vector<int> nearest_;  // per image column: index into lines_, −1 none
  std::vector<Line> lines_;
};

}  // namespace marglab
