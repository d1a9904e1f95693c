#include "core/sim/trajectory_spline.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "core/common/error.h"
#include "core/geometry/so3.h"

namespace marglab {

namespace {

// Uniform cubic B-spline basis and its first two u-derivatives at u (header: B_j).
struct Basis {
  std::array<double, 4> b, db, ddb;
};

Basis basis(double u) {
  const double u2 = u * u, u3 = u2 * u, w = 1.0 - u;
  Basis B;
  B.b = {w * w * w / 6.0, (3 * u3 - 6 * u2 + 4) / 6.0, (-3 * u3 + 3 * u2 + 3 * u + 1) / 6.0,
         u3 / 6.0};
  B.db = {-w * w / 2.0, (9 * u2 - 12 * u) / 6.0, (-9 * u2 + 6 * u + 3) / 6.0, u2 / 2.0};
  B.ddb = {w, 3 * u - 2, -3 * u + 1, u};
  return B;
}

// Cumulative basis B̃_1..3 and u-derivatives (index 0 unused: B̃_0 = 1).
Basis cumulativeBasis(double u) {
  const double u2 = u * u, u3 = u2 * u;
  Basis B;
  B.b = {1.0, (5 + 3 * u - 3 * u2 + u3) / 6.0, (1 + 3 * u + 3 * u2 - 2 * u3) / 6.0, u3 / 6.0};
  B.db = {0.0, (3 - 6 * u + 3 * u2) / 6.0, (3 + 6 * u - 6 * u2) / 6.0, u2 / 2.0};
  B.ddb = {0.0, u - 1, 1 - 2 * u, u};
  return B;
}

// GT rotation at t (slerp between neighbours; clamped to the ends).
Eigen::Quaterniond slerpGt(const Trajectory& gt, int64_t t) {
  if (t <= gt.t_ns.front()) return gt.q_w_b.front();
  if (t >= gt.t_ns.back()) return gt.q_w_b.back();
  const auto it = std::upper_bound(gt.t_ns.begin(), gt.t_ns.end(), t);
  const std::size_t k = static_cast<std::size_t>(it - gt.t_ns.begin());
  const double s =
      static_cast<double>(t - gt.t_ns[k - 1]) / static_cast<double>(gt.t_ns[k] - gt.t_ns[k - 1]);
  return gt.q_w_b[k - 1].slerp(s, gt.q_w_b[k]).normalized();
}

// Least-squares fit on one knot grid: per-sample segment and basis, and the factorization of
// N = AᵀA + λ DᵀD (header).
class GridFit {
 public:
  GridFit(const TrajectorySpline::Grid& grid, const std::vector<int64_t>& t_ns, double lambda)
      : n_(grid.segments + 3), seg_(t_ns.size()), w_(t_ns.size()) {
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(t_ns.size() * 16 + n_ * 9);
    for (std::size_t k = 0; k < t_ns.size(); ++k) {
      double u = 0;
      seg_[k] = grid.segment(t_ns[k], &u);
      w_[k] = basis(u).b;
      for (int a = 0; a < 4; ++a) {
        for (int b = 0; b < 4; ++b) {
          triplets.emplace_back(index(seg_[k] + a), index(seg_[k] + b), w_[k][a] * w_[k][b]);
        }
      }
    }
    const std::array<double, 3> d2 = {1.0, -2.0, 1.0};
    for (std::size_t m = 1; m + 1 < n_; ++m) {
      for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) {
          triplets.emplace_back(index(m - 1 + a), index(m - 1 + b), lambda * d2[a] * d2[b]);
        }
      }
    }
    Eigen::SparseMatrix<double> N(index(n_), index(n_));
    N.setFromTriplets(triplets.begin(), triplets.end());
    solver_.compute(N);
    if (solver_.info() != Eigen::Success) {
      throw InputError("", 0, "trajectory spline: normal equations not positive definite");
    }
  }

  // X (n × 3) solving N X = Σ_k b_k r_kᵀ, for the residual rows r_k = residual(k).
  template <typename Residual>
  Eigen::MatrixXd solve(Residual&& residual) const {
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(index(n_), 3);
    for (std::size_t k = 0; k < seg_.size(); ++k) {
      const Eigen::Vector3d r = residual(k);
      for (int a = 0; a < 4; ++a) rhs.row(index(seg_[k] + a)) += w_[k][a] * r.transpose();
    }
    return solver_.solve(rhs);
  }

  std::size_t size() const { return n_; }

 private:
  static Eigen::Index index(std::size_t i) { return static_cast<Eigen::Index>(i); }

  std::size_t n_;
  std::vector<std::size_t> seg_;
  std::vector<std::array<double, 4>> w_;
  // Banded: the natural order has no fill-in.
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>>
      solver_;
};

TrajectorySpline::Grid makeGrid(int64_t start_ns, int64_t end_ns, double dt_s) {
  TrajectorySpline::Grid g;
  g.t0_ns = start_ns;
  g.dt_ns = std::max<int64_t>(1, std::llround(dt_s * 1e9));
  g.segments =
      static_cast<std::size_t>(std::max<int64_t>(1, (end_ns - start_ns + g.dt_ns - 1) / g.dt_ns));
  return g;
}

}  // namespace

std::size_t TrajectorySpline::Grid::segment(int64_t t_ns, double* u) const {
  const int64_t rel = t_ns - t0_ns;
  const int64_t i =
      std::clamp<int64_t>(rel >= 0 ? rel / dt_ns : 0, 0, static_cast<int64_t>(segments) - 1);
  *u = static_cast<double>(rel - i * dt_ns) / static_cast<double>(dt_ns);
  return static_cast<std::size_t>(i);
}

struct TrajectorySpline::Eval {
  TrajectorySample s;
  Eigen::Vector3d alpha_b = Eigen::Vector3d::Zero();
};

TrajectorySpline::TrajectorySpline(const Trajectory& gt, const TrajectorySplineOptions& options) {
  if (gt.size() < 2) throw InputError("", 0, "trajectory spline: need at least 2 poses");
  for (std::size_t k = 1; k < gt.size(); ++k) {
    if (gt.t_ns[k] <= gt.t_ns[k - 1]) {
      throw InputError(
          "", 0,
          "trajectory spline: pose times not strictly increasing at index " + std::to_string(k));
    }
  }
  if (!(options.knot_dt_s > 0) || !(options.rotation_knot_dt_s > 0)) {
    throw InputError("", 0, "trajectory spline: knot spacings must be > 0");
  }
  fit(gt, options);
}

TrajectorySplineOptions TrajectorySpline::defaultOptions(DatasetKind kind) {
  TrajectorySplineOptions o;
  switch (kind) {
    case DatasetKind::kEuroc:
      o.knot_dt_s = 0.05;
      o.rotation_knot_dt_s = 0.01;
      break;
    case DatasetKind::kTumvi:
      o.knot_dt_s = 0.2;
      o.rotation_knot_dt_s = 0.2;
      break;
    case DatasetKind::kKitti:
      o.knot_dt_s = 0.1;
      o.rotation_knot_dt_s = 0.1;
      break;
  }
  return o;
}

TrajectorySpline TrajectorySpline::fromSequence(const Sequence& sequence, double knot_dt_s,
                                                double rotation_knot_dt_s) {
  if (!sequence.hasTrajectory()) {
    throw InputError(sequence.directory, 0,
                     sequence.name + " has no trajectory: cannot build a trajectory spline");
  }
  TrajectorySplineOptions options = defaultOptions(sequence.kind);
  if (knot_dt_s > 0) options.knot_dt_s = knot_dt_s;
  if (rotation_knot_dt_s > 0) options.rotation_knot_dt_s = rotation_knot_dt_s;
  try {
    return TrajectorySpline(sequence.gt, options);
  } catch (const InputError& e) {
    throw InputError(sequence.gt_file, 0, e.detail());
  }
}

void TrajectorySpline::fit(const Trajectory& gt, const TrajectorySplineOptions& options) {
  start_ns_ = gt.t_ns.front();
  end_ns_ = gt.t_ns.back();
  pos_grid_ = makeGrid(start_ns_, end_ns_, options.knot_dt_s);
  rot_grid_ = makeGrid(start_ns_, end_ns_, options.rotation_knot_dt_s);
  const std::size_t num_samples = gt.size();

  // Position: one linear solve.
  const GridFit pos_fit(pos_grid_, gt.t_ns, options.smoothing);
  const Eigen::MatrixXd c = pos_fit.solve([&](std::size_t k) { return gt.p_w_b[k]; });
  pos_.resize(pos_fit.size());
  for (std::size_t m = 0; m < pos_.size(); ++m) {
    pos_[m] = c.row(static_cast<Eigen::Index>(m)).transpose();
  }

  // Rotation: start from the GT at each control point's knot, then iterate (header).
  const GridFit rot_fit(rot_grid_, gt.t_ns, options.smoothing);
  const std::size_t n = rot_fit.size();
  rot_.resize(n);
  rot_diff_.assign(n, Eigen::Vector3d::Zero());
  for (std::size_t m = 0; m < n; ++m) {
    rot_[m] = slerpGt(gt, rot_grid_.t0_ns + (static_cast<int64_t>(m) - 1) * rot_grid_.dt_ns);
  }
  auto updateDiffs = [&]() {
    for (std::size_t m = 1; m < n; ++m) rot_diff_[m] = logSO3(rot_[m - 1].conjugate() * rot_[m]);
  };
  updateDiffs();
  report_.rotation_iterations = 0;
  for (int it = 0; it < options.max_rotation_iterations; ++it) {
    const Eigen::MatrixXd delta = rot_fit.solve([&](std::size_t k) {
      const Eigen::Quaterniond q(evaluateFull(gt.t_ns[k], false).s.R_w_b);
      return logSO3(Eigen::Quaterniond(gt.q_w_b[k] * q.conjugate()));
    });
    double max_step = 0;
    for (std::size_t m = 0; m < n; ++m) {
      const Eigen::Vector3d d = delta.row(static_cast<Eigen::Index>(m)).transpose();
      max_step = std::max(max_step, d.norm());
      rot_[m] = (expSO3Quaternion(d) * rot_[m]).normalized();
    }
    updateDiffs();
    report_.rotation_iterations = it + 1;
    if (max_step < options.rotation_tolerance_rad) break;
  }

  // Residuals at the GT samples.
  report_.knot_dt_s = static_cast<double>(pos_grid_.dt_ns) * 1e-9;
  report_.rotation_knot_dt_s = static_cast<double>(rot_grid_.dt_ns) * 1e-9;
  report_.gt_samples = num_samples;
  report_.control_points = pos_.size();
  report_.rotation_control_points = n;
  double pos_sq = 0, rot_sq = 0;
  for (std::size_t k = 0; k < num_samples; ++k) {
    const TrajectorySample s = evaluateFull(gt.t_ns[k], false).s;
    const double ep = (s.p_w_b - gt.p_w_b[k]).norm();
    const double er =
        logSO3(Eigen::Quaterniond(gt.q_w_b[k] * Eigen::Quaterniond(s.R_w_b).conjugate())).norm();
    pos_sq += ep * ep;
    rot_sq += er * er;
    if (ep > report_.position_max_m) {
      report_.position_max_m = ep;
      report_.position_max_t_ns = gt.t_ns[k];
    }
    if (er > report_.rotation_max_rad) {
      report_.rotation_max_rad = er;
      report_.rotation_max_t_ns = gt.t_ns[k];
    }
    if (k > 0) {
      report_.max_gt_gap_s =
          std::max(report_.max_gt_gap_s, static_cast<double>(gt.t_ns[k] - gt.t_ns[k - 1]) * 1e-9);
    }
  }
  report_.position_rms_m = std::sqrt(pos_sq / static_cast<double>(num_samples));
  report_.rotation_rms_rad = std::sqrt(rot_sq / static_cast<double>(num_samples));
}

TrajectorySpline::Eval TrajectorySpline::evaluateFull(int64_t t_ns,
                                                      bool angular_acceleration) const {
  Eval e;
  double u = 0;
  std::size_t i = pos_grid_.segment(t_ns, &u);
  double inv_dt = 1e9 / static_cast<double>(pos_grid_.dt_ns);
  const Basis B = basis(u);
  for (int j = 0; j < 4; ++j) {
    e.s.p_w_b += B.b[j] * pos_[i + j];
    e.s.v_w += (B.db[j] * inv_dt) * pos_[i + j];
    e.s.a_w += (B.ddb[j] * inv_dt * inv_dt) * pos_[i + j];
  }

  i = rot_grid_.segment(t_ns, &u);
  inv_dt = 1e9 / static_cast<double>(rot_grid_.dt_ns);
  const Basis Bc = cumulativeBasis(u);
  Eigen::Matrix3d R = rot_[i].toRotationMatrix();
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();
  Eigen::Vector3d alpha = Eigen::Vector3d::Zero();
  for (int j = 1; j < 4; ++j) {
    const Eigen::Vector3d& d = rot_diff_[i + j];
    const Eigen::Matrix3d A = expSO3<double>(Bc.b[j] * d);
    const double dB = Bc.db[j] * inv_dt;
    R = R * A;
    omega = A.transpose() * omega + dB * d;
    if (angular_acceleration) {
      alpha = A.transpose() * alpha + (Bc.ddb[j] * inv_dt * inv_dt) * d + dB * omega.cross(d);
    }
  }
  e.s.R_w_b = R;
  e.s.omega_b = omega;
  e.alpha_b = alpha;
  return e;
}

TrajectorySample TrajectorySpline::evaluate(int64_t t_ns) const {
  return evaluateFull(t_ns, false).s;
}

Eigen::Vector3d TrajectorySpline::angularAccelerationBody(int64_t t_ns) const {
  return evaluateFull(t_ns, true).alpha_b;
}

}  // namespace marglab
