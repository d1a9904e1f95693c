#include "core/frontend/stereo_bias.h"

#include <fmt/core.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "core/common/error.h"
#include "core/common/scalar.h"
#include "core/common/statistics.h"
#include "core/frontend/track_source.h"

namespace marglab {

namespace {

template <typename Scalar>
using Vec2S = Eigen::Matrix<Scalar, 2, 1>;
template <typename Scalar>
using Vec3S = Eigen::Matrix<Scalar, 3, 1>;
template <typename Scalar>
using Mat3S = Eigen::Matrix<Scalar, 3, 3>;

// The linear start: per view (r1 − x r3) X = x t3 − t1, (r2 − y r3) X = y t3 − t2.
template <typename Scalar>
Vec3S<Scalar> linearPoint(const std::vector<SE3<Scalar>>& T_c_w,
                          const std::vector<Vec2S<Scalar>>& uv, const PinholeCamera<Scalar>& cam) {
  const Eigen::Index n = static_cast<Eigen::Index>(uv.size());
  Eigen::Matrix<Scalar, Eigen::Dynamic, 3> A(2 * n, 3);
  Eigen::Matrix<Scalar, Eigen::Dynamic, 1> rhs(2 * n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const Mat3S<Scalar> R = T_c_w[k].rotationMatrix();
    const Vec3S<Scalar>& t = T_c_w[k].translation();
    const Scalar x = (uv[k].x() - cam.cx) / cam.fx, y = (uv[k].y() - cam.cy) / cam.fy;
    A.row(2 * k) = R.row(0) - x * R.row(2);
    A.row(2 * k + 1) = R.row(1) - y * R.row(2);
    rhs(2 * k) = x * t.z() - t.x();
    rhs(2 * k + 1) = y * t.z() - t.y();
  }
  return A.colPivHouseholderQr().solve(rhs);
}

// JᵀJ and Jᵀr of the reprojection residuals at p_w; false when a point is behind a camera.
template <typename Scalar>
bool normalEquations(const std::vector<SE3<Scalar>>& T_c_w, const std::vector<Vec2S<Scalar>>& uv,
                     const PinholeCamera<Scalar>& cam, const Vec3S<Scalar>& p_w, Mat3S<Scalar>* H,
                     Vec3S<Scalar>* g, Scalar* r2) {
  H->setZero();
  g->setZero();
  *r2 = 0;
  for (std::size_t k = 0; k < uv.size(); ++k) {
    Vec2S<Scalar> proj;
    Eigen::Matrix<Scalar, 2, 3> d_uv_d_p;
    if (!cam.project(T_c_w[k] * p_w, &proj, &d_uv_d_p)) return false;
    const Eigen::Matrix<Scalar, 2, 3> J = d_uv_d_p * T_c_w[k].rotationMatrix();
    const Vec2S<Scalar> r = proj - uv[k];
    *H += J.transpose() * J;
    *g += J.transpose() * r;
    *r2 += r.squaredNorm();
  }
  return true;
}

}  // namespace

template <typename Scalar>
std::optional<MotionTriangulation<Scalar>> triangulateFromMotion(
    const std::vector<SE3<Scalar>>& T_c_w, const std::vector<Vec2S<Scalar>>& uv,
    const PinholeCamera<Scalar>& cam, int iterations) {
  if (uv.size() < 2 || uv.size() != T_c_w.size()) return std::nullopt;
  MotionTriangulation<Scalar> out;
  out.p_w = linearPoint(T_c_w, uv, cam);
  Mat3S<Scalar> H = Mat3S<Scalar>::Zero();
  Vec3S<Scalar> g = Vec3S<Scalar>::Zero();
  Scalar r2 = 0;
  iterations = std::max(iterations, 0);
  const Scalar max_condition = Scalar(1) / (Scalar(100) * NumericTraits<Scalar>::kEpsilon);
  for (int it = 0; it <= iterations; ++it) {
    if (!normalEquations(T_c_w, uv, cam, out.p_w, &H, &g, &r2)) return std::nullopt;
    const Eigen::SelfAdjointEigenSolver<Mat3S<Scalar>> eig(H);
    const Scalar lo = eig.eigenvalues()(0), hi = eig.eigenvalues()(2);
    if (!(lo > 0) || hi > max_condition * lo) return std::nullopt;
    if (it == iterations) break;
    const Vec3S<Scalar> step =
        -eig.eigenvectors() *
        (eig.eigenvalues().cwiseInverse().asDiagonal() * (eig.eigenvectors().transpose() * g));
    out.p_w += step;
    if (step.norm() <= NumericTraits<Scalar>::kEpsilon * out.p_w.norm()) {
      iterations = it + 1;  // one more pass: H, the residuals and the checks at the new point
    }
  }
  out.rms_px = std::sqrt(r2 / static_cast<Scalar>(2 * uv.size()));
  out.cov_per_px2 = H.inverse();
  return out;
}

#define MARGLAB_INST(S)                                                       \
  template std::optional<MotionTriangulation<S>> triangulateFromMotion<S>(    \
      const std::vector<SE3<S>>&, const std::vector<Eigen::Matrix<S, 2, 1>>&, \
      const PinholeCamera<S>&, int);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

namespace {

struct TrackObservation {
  int frame;
  const StereoObservation* obs;
};

// The observations of frames [first, last] by track id.
std::map<int64_t, std::vector<TrackObservation>> tracksOf(const TrackStream& stream, int first,
                                                          int last) {
  std::map<int64_t, std::vector<TrackObservation>> tracks;
  for (int k = first; k <= last; ++k) {
    for (const StereoObservation& obs : stream.frames[static_cast<std::size_t>(k)].observations) {
      tracks[obs.track_id].push_back({k, &obs});
    }
  }
  return tracks;
}

double cameraTravel(const std::vector<TrackObservation>& track,
                    const std::vector<SE3<double>>& T_w_c) {
  const Eigen::Vector3d c0 = T_w_c[static_cast<std::size_t>(track.front().frame)].translation();
  double travel = 0;
  for (const TrackObservation& o : track) {
    travel = std::max(travel, (T_w_c[static_cast<std::size_t>(o.frame)].translation() - c0).norm());
  }
  return travel;
}

// Step 2 for one triangulated track.
void addSamples(const std::vector<TrackObservation>& track, const std::vector<SE3<double>>& T_c_w,
                const MotionTriangulation<double>& tri, const RectifiedStereo& stereo,
                const MotionStereoSettings& settings, std::vector<DisparitySample>* out) {
  const double fb = stereo.f * stereo.baseline_m;
  const double noise = std::max(tri.rms_px, settings.min_noise_px);
  for (const TrackObservation& o : track) {
    if (!o.obs->has_right) continue;
    const SE3<double>& T = T_c_w[static_cast<std::size_t>(o.frame)];
    const double z = (T * tri.p_w).z();
    const Eigen::Vector3d grad = -fb / (z * z) * T.rotationMatrix().row(2).transpose();
    DisparitySample s;
    s.frame = o.frame;
    s.u0 = o.obs->uv0.x();
    s.v0 = o.obs->uv0.y();
    s.d_stereo = (o.obs->uv0.x() - o.obs->uv1.x()) - (stereo.cx0 - stereo.cx1);
    s.d_motion = fb / z;
    s.sigma = std::sqrt(grad.dot(tri.cov_per_px2 * grad)) * noise;
    s.z = z;
    s.dv = o.obs->uv1.y() - o.obs->uv0.y();
    if (s.sigma <= settings.max_sigma_px) out->push_back(s);
  }
}

}  // namespace

std::vector<DisparitySample> motionStereoSamples(const TrackStream& stream,
                                                 const std::vector<SE3<double>>& T_w_c,
                                                 const RectifiedStereo& stereo, int first, int last,
                                                 const MotionStereoSettings& settings,
                                                 int* tracks_used) {
  std::vector<SE3<double>> T_c_w;
  for (const SE3<double>& T : T_w_c) T_c_w.push_back(T.inverse());
  PinholeCamera<double> cam;
  cam.fx = cam.fy = stereo.f;
  cam.cx = stereo.cx0;
  cam.cy = stereo.cy;
  cam.min_depth = 0.1;
  std::vector<DisparitySample> out;
  int used = 0;
  for (const auto& [id, track] : tracksOf(stream, first, last)) {
    if (static_cast<int>(track.size()) < settings.min_frames) continue;
    if (cameraTravel(track, T_w_c) < settings.min_motion_m) continue;
    std::vector<SE3<double>> poses;
    std::vector<Eigen::Vector2d> uv;
    for (const TrackObservation& o : track) {
      poses.push_back(T_c_w[static_cast<std::size_t>(o.frame)]);
      uv.push_back(o.obs->uv0);
    }
    const auto tri = triangulateFromMotion(poses, uv, cam);
    if (!tri || tri->rms_px > settings.max_rms_px) continue;
    ++used;
    addSamples(track, T_c_w, *tri, stereo, settings, &out);
  }
  if (tracks_used != nullptr) *tracks_used = used;
  return out;
}

namespace {

double standardError(const std::vector<double>& v) {
  const double m = mean(v);
  double ss = 0;
  for (double x : v) ss += (x - m) * (x - m);
  return std::sqrt(ss / static_cast<double>(v.size())) / std::sqrt(static_cast<double>(v.size()));
}

template <typename Key>
std::vector<ErrorBin> binned(const std::vector<DisparitySample>& samples,
                             const std::vector<double>& edges, Key key) {
  std::vector<ErrorBin> bins;
  for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
    std::vector<double> e, rel, dv;
    for (const DisparitySample& s : samples) {
      const double k = key(s);
      if (k < edges[b] || k >= edges[b + 1]) continue;
      e.push_back(s.error());
      rel.push_back(-s.error() / s.d_stereo);
      dv.push_back(s.dv);
    }
    if (e.size() < 5) continue;
    bins.push_back({edges[b], edges[b + 1], static_cast<int>(e.size()), mean(e), median(e),
                    standardError(e), median(rel), median(dv)});
  }
  return bins;
}

std::vector<int> sixthEdges(int size) {
  std::vector<int> edges;
  for (int i = 0; i <= 6; ++i) edges.push_back(static_cast<int>(std::lround(i * size / 6.0)));
  return edges;
}

std::vector<double> asDoubles(const std::vector<int>& v) { return {v.begin(), v.end()}; }

}  // namespace

OffsetScaleFit fitOffsetScale(const std::vector<DisparitySample>& samples, double min_noise) {
  const Eigen::Index n = static_cast<Eigen::Index>(samples.size());
  Eigen::MatrixX2d A(n, 2);
  Eigen::VectorXd y(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const DisparitySample& s = samples[static_cast<std::size_t>(i)];
    const double w = std::sqrt(1.0 / (s.sigma * s.sigma + min_noise * min_noise));
    A.row(i) << w, w * s.d_motion;
    y(i) = w * s.error();
  }
  const Eigen::Vector2d sol = A.colPivHouseholderQr().solve(y);
  const double s2 =
      (A * sol - y).squaredNorm() / static_cast<double>(std::max<Eigen::Index>(n - 2, 1));
  const Eigen::Matrix2d cov = s2 * (A.transpose() * A).inverse();
  return {sol(0), sol(1), std::sqrt(cov(0, 0)), std::sqrt(cov(1, 1))};
}

DisparityErrorSummary summarizeDisparityErrors(const std::vector<DisparitySample>& samples,
                                               double min_noise_px, int width, int height) {
  DisparityErrorSummary out;
  out.n = static_cast<int>(samples.size());
  std::vector<double> e, rel, dv;
  for (const DisparitySample& s : samples) {
    e.push_back(s.error());
    rel.push_back(-s.error() / s.d_stereo);
    dv.push_back(s.dv);
  }
  out.median = median(e);
  out.mean = mean(e);
  out.se = standardError(e);
  std::vector<double> deviation;
  for (double x : e) deviation.push_back(std::abs(x - out.median));
  out.spread = 1.4826 * median(deviation);
  out.rel_depth_error = median(rel);
  out.dv = median(dv);
  const OffsetScaleFit fit = fitOffsetScale(samples, min_noise_px);
  out.fit_c = fit.c;
  out.fit_s = fit.s;
  out.fit_c_se = fit.c_se;
  out.fit_s_se = fit.s_se;
  const double inf = std::numeric_limits<double>::infinity();
  out.by_depth = binned(samples, {0, 8, 12, 16, 20, 30, 45, inf},
                        [](const DisparitySample& s) { return s.z; });
  out.by_column =
      binned(samples, asDoubles(sixthEdges(width)), [](const DisparitySample& s) { return s.u0; });
  out.by_row =
      binned(samples, asDoubles(sixthEdges(height)), [](const DisparitySample& s) { return s.v0; });
  return out;
}

VerticalField verticalMisalignment(const TrackStream& stream, int first, int last, int width,
                                   int height) {
  VerticalField field;
  field.row_edges = sixthEdges(height);
  field.column_edges = sixthEdges(width);
  std::vector<std::vector<double>> cells(36);
  std::vector<double> all;
  const auto cellOf = [](const std::vector<int>& edges, double x) {
    const auto it = std::upper_bound(edges.begin(), edges.end(), x);
    return static_cast<int>(it - edges.begin()) - 1;
  };
  for (int k = first; k <= last; ++k) {
    for (const StereoObservation& obs : stream.frames[static_cast<std::size_t>(k)].observations) {
      if (!obs.has_right) continue;
      const int r = cellOf(field.row_edges, obs.uv0.y()),
                c = cellOf(field.column_edges, obs.uv0.x());
      const double dv = obs.uv1.y() - obs.uv0.y();
      all.push_back(dv);
      if (r >= 0 && r < 6 && c >= 0 && c < 6)
        cells[static_cast<std::size_t>(6 * r + c)].push_back(dv);
    }
  }
  for (const auto& cell : cells) {
    field.median_dv.push_back(cell.size() < 5 ? std::numeric_limits<double>::quiet_NaN()
                                              : median(cell));
  }
  field.n = static_cast<int>(all.size());
  field.overall = median(all);
  return field;
}

}  // namespace marglab
