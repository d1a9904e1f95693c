#include "core/frontend/affine_patch_tracker.h"

#include <Eigen/Dense>
#include <cmath>

namespace marglab {
namespace {

// Bilinear sample of an 8-bit image; false outside [0, cols−1) × [0, rows−1).
bool sample(const cv::Mat& image, double u, double v, double* out) {
  if (!(u >= 0 && v >= 0 && u < image.cols - 1 && v < image.rows - 1)) return false;
  const int iu = static_cast<int>(u), iv = static_cast<int>(v);
  const double a = u - iu, b = v - iv;
  const uchar* r0 = image.ptr<uchar>(iv) + iu;
  const uchar* r1 = image.ptr<uchar>(iv + 1) + iu;
  *out = (1 - b) * ((1 - a) * r0[0] + a * r0[1]) + b * ((1 - a) * r1[0] + a * r1[1]);
  return true;
}

// Level 0 stops at ‖Δt‖ < 0.01 px; a last step below kConvergedPx still counts as converged (on
// real images the iteration often settles into ~0.02 px oscillations the 0.2 px round-trip check
// does not care about).
constexpr double kConvergedPx = 0.05;

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// The template of one level: mean-normalized values and the rows gᵀJ of the steepest descent.
struct Template {
  std::vector<Eigen::Vector2d> u;
  std::vector<double> value;
  std::vector<Vector6d> sd;
  std::vector<Eigen::Vector2d> gradient;  // the last two entries of sd: the shift-only rows
  Eigen::LDLT<Matrix6d> H;
  Eigen::LDLT<Eigen::Matrix2d> H_shift;  // the translation block alone
};

bool makeTemplate(const cv::Mat& image, const Eigen::Vector2d& x, int radius, Template* t) {
  const int n = 2 * radius + 1;
  // One pixel more on each side for the central differences.
  std::vector<double> grid(static_cast<std::size_t>((n + 2) * (n + 2)));
  double sum = 0;
  for (int j = -radius - 1; j <= radius + 1; ++j) {
    for (int i = -radius - 1; i <= radius + 1; ++i) {
      double& g = grid[static_cast<std::size_t>((j + radius + 1) * (n + 2) + i + radius + 1)];
      if (!sample(image, x.x() + i, x.y() + j, &g)) return false;
      if (std::abs(i) <= radius && std::abs(j) <= radius) sum += g;
    }
  }
  const double mean = sum / (n * n);
  if (mean < 1) return false;  // black patch: nothing to normalize by
  auto at = [&](int i, int j) {
    return grid[static_cast<std::size_t>((j + radius + 1) * (n + 2) + i + radius + 1)] / mean;
  };
  Matrix6d H = Matrix6d::Zero();
  for (int j = -radius; j <= radius; ++j) {
    for (int i = -radius; i <= radius; ++i) {
      const double gx = 0.5 * (at(i + 1, j) - at(i - 1, j));
      const double gy = 0.5 * (at(i, j + 1) - at(i, j - 1));
      Vector6d sd;
      sd << gx * i, gx * j, gy * i, gy * j, gx, gy;
      t->u.emplace_back(i, j);
      t->value.push_back(at(i, j));
      t->sd.push_back(sd);
      t->gradient.emplace_back(gx, gy);
      H += sd * sd.transpose();
    }
  }
  t->H.compute(H);
  t->H_shift.compute(H.bottomRightCorner<2, 2>());
  return t->H.info() == Eigen::Success && t->H.vectorD().minCoeff() > 1e-9 &&
         t->H_shift.vectorD().minCoeff() > 1e-9;
}

// The image under the warp at the template's grid, divided by its mean; false outside the image
// or black.
bool warpedPatch(const Template& t, const cv::Mat& image, const AffinePatch& warp,
                 std::vector<double>* warped) {
  double sum = 0;
  warped->resize(t.u.size());
  for (std::size_t k = 0; k < t.u.size(); ++k) {
    const Eigen::Vector2d p = warp.x + warp.A * t.u[k];
    if (!sample(image, p.x(), p.y(), &(*warped)[k])) return false;
    sum += (*warped)[k];
  }
  const double mean = sum / static_cast<double>(t.u.size());
  if (mean < 1) return false;
  for (double& w : *warped) w /= mean;
  return true;
}

// Zero-mean NCC of two equally long value lists; −1 when either is flat.
double zeroMeanNcc(const std::vector<double>& a, const std::vector<double>& b) {
  const auto n = static_cast<double>(a.size());
  double ma = 0, mb = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    ma += a[k] / n;
    mb += b[k] / n;
  }
  double ab = 0, aa = 0, bb = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    ab += (a[k] - ma) * (b[k] - mb);
    aa += (a[k] - ma) * (a[k] - ma);
    bb += (b[k] - mb) * (b[k] - mb);
  }
  if (aa < 1e-12 || bb < 1e-12) return -1;
  return ab / std::sqrt(aa * bb);
}

// Gauss–Newton on one level until ‖Δt‖ < stop_px; x is in that level's pixels; `affine` false:
// the shift only (A kept). Returns the last ‖Δt‖, or −1 on failure.
double iterateLevel(const Template& t, const cv::Mat& image, int max_iterations, bool affine,
                    double stop_px, AffinePatch* warp) {
  double step = -1;
  std::vector<double> warped;
  for (int it = 0; it < max_iterations; ++it) {
    if (!warpedPatch(t, image, *warp, &warped)) return -1;
    Vector6d delta = Vector6d::Zero();
    if (affine) {
      Vector6d b = Vector6d::Zero();
      for (std::size_t k = 0; k < t.u.size(); ++k) b += t.sd[k] * (warped[k] - t.value[k]);
      delta = t.H.solve(b);
    } else {
      Eigen::Vector2d b = Eigen::Vector2d::Zero();
      for (std::size_t k = 0; k < t.u.size(); ++k) b += t.gradient[k] * (warped[k] - t.value[k]);
      delta.tail<2>() = t.H_shift.solve(b);
    }
    Eigen::Matrix2d dA;
    dA << 1 + delta(0), delta(1), delta(2), 1 + delta(3);
    if (std::abs(dA.determinant()) < 1e-6) return -1;
    warp->A = warp->A * dA.inverse();
    warp->x -= warp->A * delta.tail<2>();
    const double det = warp->A.determinant();
    if (!(det > 0.25 && det < 4)) return -1;
    step = delta.tail<2>().norm();
    if (step < stop_px) break;
  }
  return step;
}

}  // namespace

bool trackAffinePatch(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
                      const Eigen::Vector2d& x_from, const AffinePatch& start, PatchWarp model,
                      int radius, int levels, int max_iterations, AffinePatch* result) {
  AffinePatch warp = start;
  double step = -1;
  Template t;
  for (int l = levels - 1; l >= 0; --l) {
    const double s = std::ldexp(1.0, -l);
    t = Template{};
    if (!makeTemplate(from[static_cast<std::size_t>(l)], s * x_from, radius, &t)) return false;
    AffinePatch level{s * warp.x, warp.A};
    // A coarse level only has to bring the next one within its reach.
    step = iterateLevel(t, to[static_cast<std::size_t>(l)], max_iterations,
                        l == 0 && model == PatchWarp::kAffine, l == 0 ? 0.01 : 0.1, &level);
    if (step < 0) return false;
    warp = {level.x / s, level.A};
  }
  std::vector<double> warped;
  if (step >= kConvergedPx || !warpedPatch(t, to[0], warp, &warped)) return false;
  warp.ncc = zeroMeanNcc(t.value, warped);
  *result = warp;
  return true;
}

}  // namespace marglab
