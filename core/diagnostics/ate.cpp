#include "core/diagnostics/ate.h"

#include <fmt/format.h>

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>

#include "core/common/atomic_file.h"
#include "core/common/error.h"

namespace marglab {

std::optional<Eigen::Vector3d> interpolatePosition(const Trajectory& gt, std::int64_t t_ns,
                                                   std::int64_t max_gap_ns) {
  if (gt.empty() || t_ns < gt.t_ns.front() || t_ns > gt.t_ns.back()) return std::nullopt;
  const auto upper = std::lower_bound(gt.t_ns.begin(), gt.t_ns.end(), t_ns);
  const std::size_t k1 = static_cast<std::size_t>(upper - gt.t_ns.begin());
  if (gt.t_ns[k1] == t_ns) return gt.p_w_b[k1];
  const std::size_t k0 = k1 - 1;  // t_ns > front, so k1 ≥ 1
  const std::int64_t gap = gt.t_ns[k1] - gt.t_ns[k0];
  if (gap > max_gap_ns) return std::nullopt;
  const double s = static_cast<double>(t_ns - gt.t_ns[k0]) / static_cast<double>(gap);
  return ((1.0 - s) * gt.p_w_b[k0] + s * gt.p_w_b[k1]).eval();
}

RigidAlignment alignRigid(const std::vector<Eigen::Vector3d>& src,
                          const std::vector<Eigen::Vector3d>& dst) {
  if (src.size() != dst.size()) throw std::invalid_argument("alignRigid: size mismatch");
  RigidAlignment a;
  if (src.empty()) return a;
  const double n = static_cast<double>(src.size());
  Eigen::Vector3d mu_s = Eigen::Vector3d::Zero(), mu_d = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < src.size(); ++i) {
    mu_s += src[i];
    mu_d += dst[i];
  }
  mu_s /= n;
  mu_d /= n;
  Eigen::Matrix3d sigma = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < src.size(); ++i)
    sigma += (dst[i] - mu_d) * (src[i] - mu_s).transpose();
  sigma /= n;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(sigma, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d s(1.0, 1.0, 1.0);
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) s(2) = -1.0;
  a.R_gt_est = svd.matrixU() * s.asDiagonal() * svd.matrixV().transpose();
  a.t_gt_est = mu_d - a.R_gt_est * mu_s;
  a.valid = true;
  return a;
}

AteResult computeAte(const std::vector<Eigen::Vector3d>& p_est,
                     const std::vector<Eigen::Vector3d>& p_gt) {
  if (p_est.size() != p_gt.size()) throw std::invalid_argument("computeAte: size mismatch");
  std::vector<std::size_t> rows;
  std::vector<Eigen::Vector3d> src, dst;
  for (std::size_t i = 0; i < p_est.size(); ++i) {
    if (!p_est[i].allFinite() || !p_gt[i].allFinite()) continue;
    rows.push_back(i);
    src.push_back(p_est[i]);
    dst.push_back(p_gt[i]);
  }
  AteResult r;
  r.n_pairs = rows.size();
  r.error.assign(p_est.size(), std::numeric_limits<double>::quiet_NaN());
  r.alignment = alignRigid(src, dst);
  if (rows.empty()) {
    r.rmse = std::numeric_limits<double>::quiet_NaN();
    return r;
  }
  double sum = 0.0;
  for (std::size_t j = 0; j < rows.size(); ++j) {
    const double e = (dst[j] - (r.alignment.R_gt_est * src[j] + r.alignment.t_gt_est)).norm();
    r.error[rows[j]] = e;
    sum += e * e;
  }
  r.rmse = std::sqrt(sum / static_cast<double>(rows.size()));
  return r;
}

AteResult computeAte(const std::vector<std::int64_t>& t_ns,
                     const std::vector<Eigen::Vector3d>& p_est, const Trajectory& gt,
                     std::int64_t max_gap_ns) {
  if (t_ns.size() != p_est.size()) throw std::invalid_argument("computeAte: size mismatch");
  std::vector<Eigen::Vector3d> p_gt(
      t_ns.size(), Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  for (std::size_t i = 0; i < t_ns.size(); ++i) {
    if (const auto p = interpolatePosition(gt, t_ns[i], max_gap_ns)) p_gt[i] = *p;
  }
  return computeAte(p_est, p_gt);
}

void writeTumTrajectory(const std::string& path, const std::vector<std::int64_t>& t_ns,
                        const std::vector<Eigen::Vector3d>& positions,
                        const std::vector<Eigen::Quaterniond>& quaternions) {
  if (t_ns.size() != positions.size() || t_ns.size() != quaternions.size()) {
    throw std::invalid_argument("writeTumTrajectory: size mismatch");
  }
  std::string text;
  for (std::size_t i = 0; i < t_ns.size(); ++i) {
    const std::int64_t t = t_ns[i];
    const std::int64_t magnitude = t < 0 ? -t : t;
    const Eigen::Vector3d& p = positions[i];
    const Eigen::Quaterniond& q = quaternions[i];
    text += fmt::format("{}{}.{:09d} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f}\n",
                        t < 0 ? "-" : "", magnitude / 1'000'000'000, magnitude % 1'000'000'000,
                        p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w());
  }
  AtomicFile file(path);
  file.write(text);
  file.commit();
}

}  // namespace marglab
