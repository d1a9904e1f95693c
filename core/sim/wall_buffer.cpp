#include "core/sim/wall_buffer.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace marglab {

WallBuffer::WallBuffer(const World& world, const Eigen::Matrix3d& R_c_w,
                       const Eigen::Vector3d& p_w_c, const CameraCalib& calib, double max_depth) {
  if (world.walls.empty()) return;
  nearest_.assign(static_cast<std::size_t>(calib.width), -1);
  std::vector<double> depth(nearest_.size(), std::numeric_limits<double>::infinity());
  constexpr double kNear = 0.1;
  for (const WallSegment& wall : world.walls) {
    const Eigen::Vector3d a = R_c_w * (wall.a_w - p_w_c);
    const Eigen::Vector3d b = R_c_w * (wall.b_w - p_w_c);
    Eigen::Vector2d A(a.x(), a.z()), B(b.x(), b.z());
    if (A.y() < kNear && B.y() < kNear) continue;
    if (std::min(A.norm(), B.norm()) > max_depth + (B - A).norm()) continue;
    // Clip to z ≥ kNear.
    if (A.y() < kNear) A += (kNear - A.y()) / (B.y() - A.y()) * (B - A);
    if (B.y() < kNear) B += (kNear - B.y()) / (A.y() - B.y()) * (A - B);
    const double uA = calib.fx * A.x() / A.y() + calib.cx;
    const double uB = calib.fx * B.x() / B.y() + calib.cx;
    const int c0 = std::max(0, static_cast<int>(std::floor(std::min(uA, uB))));
    const int c1 = std::min(calib.width - 1, static_cast<int>(std::ceil(std::max(uA, uB))));
    if (c0 > c1) continue;
    const Eigen::Vector2d D = B - A;
    const auto index = static_cast<int>(lines_.size());
    lines_.push_back({A, D});
    for (int c = c0; c <= c1; ++c) {
      const double z = lineDepth(lines_.back(), (c - calib.cx) / calib.fx);
      if (z > 0 && z < depth[c]) {
        depth[c] = z;
        nearest_[c] = index;
      }
    }
  }
}

bool WallBuffer::hidden(const Eigen::Vector3d& p_c, const Eigen::Vector2d& uv) const {
  if (nearest_.empty()) return false;
  const auto c = static_cast<std::size_t>(std::clamp(static_cast<long>(std::lround(uv.x())), 0L,
                                                     static_cast<long>(nearest_.size()) - 1));
  if (nearest_[c] < 0) return false;
  const double z_wall = lineDepth(lines_[nearest_[c]], p_c.x() / p_c.z());
  return z_wall > 0 && p_c.z() > z_wall * (1 + 1e-9) + 1e-3;
}

double WallBuffer::lineDepth(const Line& line, double t) {
  const double denom = t * line.D.y() - line.D.x();
  if (denom == 0) return std::numeric_limits<double>::infinity();
  return (line.A.x() * line.D.y() - line.A.y() * line.D.x()) / denom;
}

}  // namespace marglab
