#include "core/frontend/optical_flow.h"

#include <fmt/core.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <optional>
#include <unordered_map>

#include "core/common/error.h"
#include "core/frontend/affine_patch_tracker.h"
#include "core/frontend/image_file.h"
#include "core/geometry/so3.h"

namespace marglab {

FrontendOptions defaultFrontendOptions(const Sequence& sequence,
                                       const FrontendOptions& configured) {
  return resolveFrontendOptions(configured, sequence.kind);
}

cv::Mat readGreyImage(const std::string& path, int width, int height) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw InputError(path, 0, "expected an image file (not found)");
  }
  cv::Mat image = decodeImageFile(path);
  if (image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2GRAY);
  if (image.depth() == CV_16U) image.convertTo(image, CV_8U, 1.0 / 256.0);
  if (image.type() != CV_8UC1) {
    throw InputError(path, 0, "expected an 8-bit grey image (or 16-bit / colour to convert)");
  }
  if (width > 0 && height > 0 && (image.cols != width || image.rows != height)) {
    throw InputError(path, 0,
                     fmt::format("expected a {}x{} image (the calibration's), found {}x{}", width,
                                 height, image.cols, image.rows));
  }
  return image;
}

namespace {

// Zero-mean normalized cross-correlation of two equally sized float patches; −1 when either is
// flat (no texture to compare).
double zeroMeanNcc(const cv::Mat& a, const cv::Mat& b) {
  cv::Scalar mean_a, std_a, mean_b, std_b;
  cv::meanStdDev(a, mean_a, std_a);
  cv::meanStdDev(b, mean_b, std_b);
  if (std_a[0] < 1e-6 || std_b[0] < 1e-6) return -1;
  const double n = static_cast<double>(a.total());
  const double cross = a.dot(b) / n - mean_a[0] * mean_b[0];
  return cross / (std_a[0] * std_b[0]);
}

Eigen::Vector3d bearingOf(const CameraModel<double>& cam, const Eigen::Vector2d& uv) {
  return Eigen::Vector3d((uv.x() - cam.cx) / cam.fx, (uv.y() - cam.cy) / cam.fy, 1).normalized();
}

cv::Point2f toPoint(const Eigen::Vector2d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y())};
}

}  // namespace

struct StereoFrontend::Impl {
  FrontendOptions options;
  CameraModel<double> cam0, cam1;
  Eigen::Matrix3d E;  // essential matrix [t̂]× R of T_c0_c1, unit translation
  SE3<double> T_c0_c1, T_c1_c0;
  double baseline = 0;
  int width = 0, height = 0;
  int64_t prev_t_ns = 0;
  std::vector<cv::Mat> prev_pyramid;
  std::vector<cv::Point2f> prev_points;  // raw left keypoints of the previous frame
  std::vector<int64_t> prev_ids;
  std::vector<Eigen::Vector2d> prev_uv;  // their undistorted (pinhole) pixels
  std::unordered_map<int64_t, Eigen::Vector3d> prev_depth_points;  // stereo points, prev cam0
  std::unordered_map<int64_t, cv::Point2f> prev_disparity;  // raw right − raw left, last frame
  std::unordered_map<int64_t, int> unmatched;  // tracks without a match: frames since their last
  std::vector<Eigen::Vector2d> last_raw_left;
  // The tracker's own motion: the last frame's geometric-check motion and its time step.
  std::optional<SE3<double>> last_motion;
  double last_motion_dt_s = 0;
  int64_t next_id = 0;

  cv::Size window() const { return {options.window_px, options.window_px}; }
  cv::TermCriteria criteria() const {
    // EPS 0.01 px: further steps would not change the keypoint at the 0.2 px check's scale.
    return {cv::TermCriteria::COUNT | cv::TermCriteria::EPS, options.max_iterations, 0.01};
  }
  bool inside(const cv::Point2f& p) const {
    const float b = static_cast<float>(options.border_px);
    return p.x >= b && p.y >= b && p.x <= static_cast<float>(width - 1) - b &&
           p.y <= static_cast<float>(height - 1) - b;
  }
  bool undistort(const CameraModel<double>& cam, const cv::Point2f& p, Eigen::Vector2d* uv) const {
    return cam.undistortPixel(Eigen::Vector2d(p.x, p.y), uv);
  }
  bool epipolarOk(const Eigen::Vector2d& uv0, const Eigen::Vector2d& uv1) const {
    return std::abs(bearingOf(cam0, uv0).dot(E * bearingOf(cam1, uv1))) <= options.epipolar_max;
  }
  // The raw pixel of a camera-frame point, if it lies in front of the camera.
  std::optional<cv::Point2f> project(const CameraModel<double>& cam,
                                     const Eigen::Vector3d& p_c) const {
    if (p_c.z() < 1e-3) return std::nullopt;
    const Eigen::Vector2d uv(cam.fx * p_c.x() / p_c.z() + cam.cx,
                             cam.fy * p_c.y() / p_c.z() + cam.cy);
    return toPoint(cam.distortPixel(uv));
  }

  std::optional<FramePrediction> ownPrediction(int64_t t_ns) const;
  std::vector<cv::Point2f> predictLeft(const FramePrediction* prediction,
                                       std::vector<bool>* predicted_out,
                                       std::vector<double>* scale) const;
  void retrackScaled(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
                     const std::vector<cv::Point2f>& start, const std::vector<double>& scale,
                     const std::vector<bool>& in_view, std::vector<cv::Point2f>* tracked,
                     std::vector<bool>* ok) const;
  std::optional<double> neighbourDepth(
      const cv::Point2f& p, const std::vector<std::pair<cv::Point2f, double>>& with_depth) const;
  bool patchesAgree(const cv::Mat& from, const cv::Point2f& a, const cv::Mat& to,
                    const cv::Point2f& b) const;
  std::vector<bool> trackForwardBackward(const std::vector<cv::Mat>& from,
                                         const std::vector<cv::Mat>& to,
                                         const std::vector<cv::Point2f>& points,
                                         std::vector<cv::Point2f>* tracked,
                                         std::vector<bool>* lk_ok, int levels) const;
  void geometricCheck(const std::vector<std::size_t>& survivors,
                      const std::vector<Eigen::Vector2d>& uv_new, std::vector<bool>* keep,
                      FrontendFrameStats* stats);
  void detect(const std::vector<cv::Mat>& pyramid, const std::vector<cv::Point2f>& occupied,
              std::vector<cv::Point2f>* found) const;
  cv::Point2f disparityGuess(const Eigen::Vector2d& uv0, double disparity_px) const;
  std::optional<Eigen::Vector3d> triangulate(const Eigen::Vector2d& uv0,
                                             const Eigen::Vector2d& uv1) const;
  void matchStereo(const std::vector<cv::Mat>& pyramid0, const std::vector<cv::Mat>& pyramid1,
                   const std::vector<cv::Point2f>& points,
                   const std::unordered_map<int64_t, cv::Point2f>& predicted_right,
                   TrackFrame* frame);
  // Steps 1–3: the previous frame's keypoints tracked into `pyramid0` and checked; the survivors
  // appended to *frame / *points, with their predicted right pixels (the stereo starts).
  void trackTemporal(const std::vector<cv::Mat>& pyramid0, const FramePrediction* prediction,
                     TrackFrame* frame, std::vector<cv::Point2f>* points,
                     std::unordered_map<int64_t, cv::Point2f>* predicted_right,
                     FrontendFrameStats* stats, std::vector<FlowCandidate>* candidates);
  // The frame becomes the previous one of the next call.
  void advance(int64_t t_ns, const FrontendFrameStats& stats, const TrackFrame& frame,
               std::vector<cv::Mat>&& pyramid0, std::vector<cv::Point2f>&& points);
};

namespace {

// A keypoint of the frame: its raw left pixel in *points, its observation in *frame.
void addKeypoint(const cv::Point2f& p, int64_t id, const Eigen::Vector2d& uv, TrackFrame* frame,
                 std::vector<cv::Point2f>* points) {
  points->push_back(p);
  StereoObservation obs;
  obs.track_id = id;
  obs.uv0 = uv;
  frame->observations.push_back(obs);
}

}  // namespace

// Constant velocity of the tracker's own motion, scaled to the new time step: T_new_prev =
// exp(s log T_last), s = Δt_new / Δt_last.
std::optional<FramePrediction> StereoFrontend::Impl::ownPrediction(int64_t t_ns) const {
  if (!last_motion || last_motion_dt_s <= 0) return std::nullopt;
  const double s = 1e-9 * static_cast<double>(t_ns - prev_t_ns) / last_motion_dt_s;
  FramePrediction prediction;
  prediction.T_new_prev = SE3<double>::exp(s * last_motion->log());
  return prediction;
}

// The LK starts of the previous keypoints (step 1); predicted_out[i] false marks a point predicted
// outside the image (its track ends).
std::vector<cv::Point2f> StereoFrontend::Impl::predictLeft(const FramePrediction* prediction,
                                                           std::vector<bool>* predicted_out,
                                                           std::vector<double>* scale) const {
  std::vector<cv::Point2f> start = prev_points;
  predicted_out->assign(prev_points.size(), true);
  scale->assign(prev_points.size(), 1.0);
  if (prediction == nullptr) return start;
  const SE3<double>& T = prediction->T_new_prev;
  std::vector<std::pair<cv::Point2f, double>> with_depth;
  for (std::size_t i = 0; i < prev_points.size(); ++i) {
    const auto point = prev_depth_points.find(prev_ids[i]);
    if (point != prev_depth_points.end()) {
      with_depth.emplace_back(prev_points[i], point->second.z());
    }
  }
  for (std::size_t i = 0; i < prev_points.size(); ++i) {
    const int64_t id = prev_ids[i];
    std::optional<Eigen::Vector3d> p_prev;
    auto window_point = prediction->p_prev.find(id);
    auto stereo_point = prev_depth_points.find(id);
    if (window_point != prediction->p_prev.end()) {
      p_prev = window_point->second;
    } else if (stereo_point != prev_depth_points.end()) {
      p_prev = stereo_point->second;
    } else if (const auto z = neighbourDepth(prev_points[i], with_depth)) {
      const Eigen::Vector3d b = bearingOf(cam0, prev_uv[i]);
      p_prev = *z / b.z() * b;
    }
    std::optional<cv::Point2f> guess;
    if (p_prev) {
      // A patch at depth z appears z_prev / z_new times larger after the motion.
      const Eigen::Vector3d p_new = T * *p_prev;
      guess = project(cam0, p_new);
      if (guess) (*scale)[i] = p_prev->z() / p_new.z();
    } else {
      guess = project(cam0, T.rotationMatrix() * bearingOf(cam0, prev_uv[i]));
    }
    if (!guess || !inside(*guess)) {
      (*predicted_out)[i] = false;
      continue;
    }
    start[i] = *guess;
  }
  return start;
}

// The depth z of the keypoint nearest to p among `with_depth` (previous keypoints with a stereo
// point), if one lies within two grid cells: a surface is mostly continuous, and a neighbour's
// depth puts the start within a few pixels where infinity is tens of pixels off for near points.
std::optional<double> StereoFrontend::Impl::neighbourDepth(
    const cv::Point2f& p, const std::vector<std::pair<cv::Point2f, double>>& with_depth) const {
  const float radius = 2.0F * static_cast<float>(options.grid_cell_px);
  float best = radius * radius;
  std::optional<double> z;
  for (const auto& [q, z_q] : with_depth) {
    const cv::Point2f d = q - p;
    if (d.dot(d) < best) {
      best = d.dot(d);
      z = z_q;
    }
  }
  return z;
}

// Step 2's patch check on the finest level.
bool StereoFrontend::Impl::patchesAgree(const cv::Mat& from, const cv::Point2f& a,
                                        const cv::Mat& to, const cv::Point2f& b) const {
  cv::Mat patch_a, patch_b;
  cv::getRectSubPix(from, window(), a, patch_a, CV_32F);
  cv::getRectSubPix(to, window(), b, patch_b, CV_32F);
  return zeroMeanNcc(patch_a, patch_b) >= options.ncc_min;
}

// LK from `from` to `to` starting at *tracked (the initial guesses), then back; ok[i] when both
// converge, the result is inside the image, the round trip returns within fb_max_px and the
// patches agree (NCC). Pyramids as cv::buildOpticalFlowPyramid with derivatives: level l's image
// is element 2l.
std::vector<bool> StereoFrontend::Impl::trackForwardBackward(const std::vector<cv::Mat>& from,
                                                             const std::vector<cv::Mat>& to,
                                                             const std::vector<cv::Point2f>& points,
                                                             std::vector<cv::Point2f>* tracked,
                                                             std::vector<bool>* lk_ok,
                                                             int levels) const {
  std::vector<bool> ok(points.size(), false);
  if (lk_ok != nullptr) lk_ok->assign(points.size(), false);
  if (points.empty()) return ok;
  const int max_level = levels - 1;
  std::vector<uchar> status, back_status;
  std::vector<float> error;
  const std::vector<cv::Point2f> start = *tracked;
  cv::calcOpticalFlowPyrLK(from, to, points, *tracked, status, error, window(), max_level,
                           criteria(), cv::OPTFLOW_USE_INITIAL_FLOW);
  // The backward pass gets the same prior as the forward one, inverted: it starts at the forward
  // result minus the forward start's offset.
  std::vector<cv::Point2f> back(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) back[i] = (*tracked)[i] - (start[i] - points[i]);
  cv::calcOpticalFlowPyrLK(to, from, *tracked, back, back_status, error, window(), max_level,
                           criteria(), cv::OPTFLOW_USE_INITIAL_FLOW);
  const double fb2 = options.fb_max_px * options.fb_max_px;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const bool forward = status[i] != 0 && inside((*tracked)[i]);
    if (lk_ok != nullptr) (*lk_ok)[i] = forward;
    const cv::Point2f d = back[i] - points[i];
    ok[i] = forward && back_status[i] != 0 && d.dot(d) <= fb2 &&
            patchesAgree(from[0], points[i], to[0], (*tracked)[i]);
  }
  return ok;
}

// Step 2b on the tracks predicted in view that failed step 2: the patch tracker of
// affine_patch_tracker.h from the prediction with the patch zoomed by the predicted scale (the
// shift estimated, the zoom held), then back from its result with the inverse zoom; the track
// continues if the round trip returns within fb_max_px and the zoomed patches agree (ncc_min).
// The inverse-compositional steps are cheap (the template's Hessian is fixed) but converge in more
// of them than Bouguet's LK: 3 max_iterations per level.
void StereoFrontend::Impl::retrackScaled(const std::vector<cv::Mat>& from,
                                         const std::vector<cv::Mat>& to,
                                         const std::vector<cv::Point2f>& start,
                                         const std::vector<double>& scale,
                                         const std::vector<bool>& in_view,
                                         std::vector<cv::Point2f>* tracked,
                                         std::vector<bool>* ok) const {
  const int levels = std::min(3, options.pyramid_levels);
  std::vector<cv::Mat> from_levels, to_levels;  // element 2l of the pyramids is level l
  for (int l = 0; l < levels; ++l) {
    from_levels.push_back(from[static_cast<std::size_t>(2 * l)]);
    to_levels.push_back(to[static_cast<std::size_t>(2 * l)]);
  }
  const int radius = options.window_px / 2;
  for (std::size_t i = 0; i < start.size(); ++i) {
    if ((*ok)[i] || !in_view[i]) continue;
    const Eigen::Vector2d x_prev(prev_points[i].x, prev_points[i].y);
    AffinePatch forward{Eigen::Vector2d(start[i].x, start[i].y),
                        scale[i] * Eigen::Matrix2d::Identity()};
    if (!trackAffinePatch(from_levels, to_levels, x_prev, forward, PatchWarp::kShift, radius,
                          levels, 3 * options.max_iterations, &forward) ||
        forward.ncc < options.ncc_min || !inside(toPoint(forward.x))) {
      continue;
    }
    // The backward start mirrors the forward one's offset from the prediction (as in step 2).
    AffinePatch back{forward.x - (Eigen::Vector2d(start[i].x, start[i].y) - x_prev),
                     forward.A.inverse()};
    if (!trackAffinePatch(to_levels, from_levels, forward.x, back, PatchWarp::kShift, radius,
                          levels, 3 * options.max_iterations, &back) ||
        (back.x - x_prev).norm() > options.fb_max_px) {
      continue;
    }
    (*tracked)[i] = toPoint(forward.x);
    (*ok)[i] = true;
  }
}

// Step 3 on the tracks that passed step 2 (survivors: indices into prev_*; uv_new their new
// pinhole pixels); clears keep[k] of the outliers. solvePnPRansac draws from its own RNG with a
// fixed seed (OpenCV ptsetreg.cpp), so the result is deterministic.
void StereoFrontend::Impl::geometricCheck(const std::vector<std::size_t>& survivors,
                                          const std::vector<Eigen::Vector2d>& uv_new,
                                          std::vector<bool>* keep, FrontendFrameStats* stats) {
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  std::vector<std::size_t> with_depth;
  for (std::size_t k = 0; k < survivors.size(); ++k) {
    const auto point = prev_depth_points.find(prev_ids[survivors[k]]);
    if (point == prev_depth_points.end()) continue;
    object.emplace_back(point->second.x(), point->second.y(), point->second.z());
    image.emplace_back(uv_new[k].x(), uv_new[k].y());
    with_depth.push_back(k);
  }
  stats->n_motion_points = static_cast<int>(object.size());
  constexpr std::size_t kMinPoints = 8;  // P3P needs 4; fewer than 8 cannot outvote outliers
  if (object.size() < kMinPoints) return;
  const cv::Matx33d K(cam0.fx, 0, cam0.cx, 0, cam0.fy, cam0.cy, 0, 0, 1);
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  if (!cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, 200,
                          static_cast<float>(options.ransac_px), 0.999, inliers,
                          cv::SOLVEPNP_P3P) ||
      inliers.size() < kMinPoints) {
    return;
  }
  cv::Matx33d R_cv;
  cv::Rodrigues(rvec, R_cv);
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = R_cv(r, c);
  const Eigen::Vector3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
  stats->T_new_prev = SE3<double>(R, t);
  stats->has_motion = true;
  stats->n_motion_inliers = static_cast<int>(inliers.size());
  std::vector<bool> inlier(with_depth.size(), false);
  for (const int i : inliers) inlier[static_cast<std::size_t>(i)] = true;
  for (std::size_t j = 0; j < with_depth.size(); ++j) {
    if (!inlier[j]) (*keep)[with_depth[j]] = false;
  }
  // Tracks without depth: the epipolar constraint of the motion, when it has a baseline.
  if (t.norm() < 0.02) return;
  const Eigen::Matrix3d E_motion = hat<double>(Eigen::Vector3d(t.normalized())) * R;
  for (std::size_t k = 0; k < survivors.size(); ++k) {
    if (prev_depth_points.count(prev_ids[survivors[k]]) != 0) continue;
    const double e =
        bearingOf(cam0, uv_new[k]).dot(E_motion * bearingOf(cam0, prev_uv[survivors[k]]));
    if (std::abs(e) > options.epipolar_max) (*keep)[k] = false;
  }
}

// Shi–Tomasi maximum in each grid cell that holds no occupied point, found on the pyramid's
// second level (half resolution: a quarter of the cost, and a corner there is one at full
// resolution too); the keypoint is the full-resolution pixel of that maximum.
void StereoFrontend::Impl::detect(const std::vector<cv::Mat>& pyramid,
                                  const std::vector<cv::Point2f>& occupied,
                                  std::vector<cv::Point2f>* found) const {
  const int c = options.grid_cell_px;
  const int nx = (width + c - 1) / c, ny = (height + c - 1) / c;
  std::vector<char> full(static_cast<std::size_t>(nx * ny), 0);
  for (const cv::Point2f& p : occupied) {
    const int i = static_cast<int>(p.x) / c, j = static_cast<int>(p.y) / c;
    if (i >= 0 && i < nx && j >= 0 && j < ny) full[static_cast<std::size_t>(j * nx + i)] = 1;
  }
  const int scale = pyramid.size() > 2 ? 2 : 1;
  const cv::Mat& image = pyramid[scale == 2 ? 2 : 0];
  const int b = options.border_px, pad = options.corner_block_px;
  const int side = std::max(b, options.detect_margin_px);
  const cv::Rect valid(side, b, width - 2 * side, height - 2 * b);
  cv::Mat response;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      if (full[static_cast<std::size_t>(j * nx + i)]) continue;
      const cv::Rect cell_full = cv::Rect(i * c, j * c, c, c) & valid;
      const cv::Rect cell(cell_full.x / scale, cell_full.y / scale, cell_full.width / scale,
                          cell_full.height / scale);
      if (cell.empty()) continue;
      // Padding so that the structure tensor at the cell's edge sees real neighbours.
      const cv::Rect padded =
          cv::Rect(cell.x - pad, cell.y - pad, cell.width + 2 * pad, cell.height + 2 * pad) &
          cv::Rect(0, 0, image.cols, image.rows);
      cv::cornerMinEigenVal(image(padded), response, options.corner_block_px, 3);
      const cv::Mat inner = response(cell - padded.tl());
      double best = 0;
      cv::Point at;
      cv::minMaxLoc(inner, nullptr, &best, nullptr, &at);
      if (best >= options.min_eigen) {
        found->emplace_back(static_cast<float>(scale * (cell.x + at.x)),
                            static_cast<float>(scale * (cell.y + at.y)));
      }
    }
  }
}

// The raw right pixel of the left keypoint uv0 (pinhole) if its stereo disparity were d pixels:
// depth z = f b / d along the left ray, mapped into cam1 (d = 0: the same raw pixel).
cv::Point2f StereoFrontend::Impl::disparityGuess(const Eigen::Vector2d& uv0,
                                                 double disparity_px) const {
  if (disparity_px <= 0) return toPoint(cam0.distortPixel(uv0));
  const double z = cam0.fx * baseline / disparity_px;
  const Eigen::Vector3d p_c0 =
      z * Eigen::Vector3d((uv0.x() - cam0.cx) / cam0.fx, (uv0.y() - cam0.cy) / cam0.fy, 1);
  const Eigen::Vector2d raw = cam1.distortPixel(
      Eigen::Vector2d(cam1.fx * (T_c1_c0 * p_c0).x() / (T_c1_c0 * p_c0).z() + cam1.cx,
                      cam1.fy * (T_c1_c0 * p_c0).y() / (T_c1_c0 * p_c0).z() + cam1.cy));
  return toPoint(raw);
}

// The point in cam0 from a stereo match: depths λ0, λ1 along the bearings b0 (cam0) and R b1
// (cam1, R t = T_c0_c1) minimizing ‖λ0 b0 − (λ1 R b1 + t)‖² (2×2 normal equations); nullopt for
// (near-)parallel rays or a point behind either camera or beyond 1000 baselines (no usable
// depth).
std::optional<Eigen::Vector3d> StereoFrontend::Impl::triangulate(const Eigen::Vector2d& uv0,
                                                                 const Eigen::Vector2d& uv1) const {
  const Eigen::Vector3d b0 = bearingOf(cam0, uv0);
  const Eigen::Vector3d b1 = T_c0_c1.rotationMatrix() * bearingOf(cam1, uv1);
  const Eigen::Vector3d& t = T_c0_c1.translation();
  Eigen::Matrix2d A;
  A << 1, -b0.dot(b1), b0.dot(b1), -1;
  const Eigen::Vector2d rhs(b0.dot(t), b1.dot(t));
  if (std::abs(A.determinant()) < 1e-9) return std::nullopt;
  const Eigen::Vector2d lambda = A.partialPivLu().solve(rhs);
  if (lambda.x() <= 0.05 || lambda.y() <= 0.05 || lambda.x() > 1000 * baseline) return std::nullopt;
  return lambda.x() * b0;
}

// Left → right matches (step 5). A track that found no match tries one disparity guess per frame
// in turn: most such points are out of the right view or occluded, and retrying every guess in
// every frame would cost most of the front-end's time.
void StereoFrontend::Impl::matchStereo(
    const std::vector<cv::Mat>& pyramid0, const std::vector<cv::Mat>& pyramid1,
    const std::vector<cv::Point2f>& points,
    const std::unordered_map<int64_t, cv::Point2f>& predicted_right, TrackFrame* frame) {
  std::unordered_map<int64_t, cv::Point2f> disparity;
  std::unordered_map<int64_t, Eigen::Vector3d> depth_points;
  std::vector<std::size_t> pending(points.size());
  for (std::size_t i = 0; i < pending.size(); ++i) pending[i] = i;
  const std::size_t guesses = options.disparity_guesses_px.size();
  for (std::size_t round = 0; round <= guesses && !pending.empty(); ++round) {
    std::vector<cv::Point2f> from, guess;
    std::vector<std::size_t> tried;
    for (const std::size_t i : pending) {
      const int64_t id = frame->observations[i].track_id;
      std::optional<cv::Point2f> start;
      if (round == 0) {
        const auto predicted = predicted_right.find(id);
        const auto prev = prev_disparity.find(id);
        if (predicted != predicted_right.end()) {
          start = predicted->second;
        } else if (prev != prev_disparity.end()) {
          start = points[i] + prev->second;
        }
      } else {
        const auto miss = unmatched.find(id);
        if (miss == unmatched.end() ||
            static_cast<std::size_t>(miss->second) % guesses == round - 1) {
          start =
              disparityGuess(frame->observations[i].uv0, options.disparity_guesses_px[round - 1]);
        }
      }
      if (!start) continue;
      from.push_back(points[i]);
      guess.push_back(*start);
      tried.push_back(i);
    }
    // From a predicted or previous disparity the start is within a pixel or two: the two finest
    // levels converge, and the coarser ones would only cost time.
    const int levels = round == 0 ? std::min(2, options.pyramid_levels) : options.pyramid_levels;
    const std::vector<bool> ok =
        trackForwardBackward(pyramid0, pyramid1, from, &guess, nullptr, levels);
    std::vector<std::size_t> still;
    for (std::size_t k = 0, j = 0; k < pending.size(); ++k) {
      const std::size_t i = pending[k];
      const bool was_tried = j < tried.size() && tried[j] == i;
      Eigen::Vector2d uv1;
      StereoObservation& obs = frame->observations[i];
      if (was_tried && ok[j] && undistort(cam1, guess[j], &uv1) && epipolarOk(obs.uv0, uv1)) {
        obs.has_right = true;
        obs.uv1 = uv1;
        disparity[obs.track_id] = guess[j] - points[i];
        if (const auto p = triangulate(obs.uv0, uv1)) depth_points[obs.track_id] = *p;
      } else {
        still.push_back(i);
      }
      if (was_tried) ++j;
    }
    pending = std::move(still);
  }
  std::unordered_map<int64_t, int> next_unmatched;
  for (const std::size_t i : pending) {
    const int64_t id = frame->observations[i].track_id;
    const auto miss = unmatched.find(id);
    next_unmatched[id] = miss == unmatched.end() ? 0 : miss->second + 1;
  }
  unmatched = std::move(next_unmatched);
  prev_disparity = std::move(disparity);
  prev_depth_points = std::move(depth_points);
}

StereoFrontend::StereoFrontend(const StereoCalib& calib, const FrontendOptions& options,
                               const std::string& calib_source)
    : impl_(std::make_unique<Impl>()) {
  cv::setNumThreads(1);  // deterministic and one core (README: front-end speed)
  Impl& m = *impl_;
  m.options = options;
  m.cam0 = cameraModelFromCalib<double>(calib.cam0, calib_source);
  m.cam1 = cameraModelFromCalib<double>(calib.cam1, calib_source);
  m.width = calib.cam0.width;
  m.height = calib.cam0.height;
  // T_c0_c1 = T_b_c0⁻¹ T_b_c1.
  m.T_c0_c1 = SE3<double>(calib.cam0.R_b_c, calib.cam0.t_b_c).inverse() *
              SE3<double>(calib.cam1.R_b_c, calib.cam1.t_b_c);
  m.T_c1_c0 = m.T_c0_c1.inverse();
  m.E = hat<double>(Eigen::Vector3d(m.T_c0_c1.translation().normalized())) *
        m.T_c0_c1.rotationMatrix();
  m.baseline = m.T_c0_c1.translation().norm();
}

StereoFrontend::~StereoFrontend() = default;
StereoFrontend::StereoFrontend(StereoFrontend&&) noexcept = default;
StereoFrontend& StereoFrontend::operator=(StereoFrontend&&) noexcept = default;

const std::vector<Eigen::Vector2d>& StereoFrontend::lastRawLeft() const {
  return impl_->last_raw_left;
}

namespace {

// The right image brought to the left's mean and contrast: the two cameras' exposures differ
// (EuRoC: mean grey 146 vs 131) and LK assumes equal brightness.
cv::Mat matchedRight(const cv::Mat& left, const cv::Mat& right) {
  cv::Scalar mean0, std0, mean1, std1;
  cv::meanStdDev(left, mean0, std0);
  cv::meanStdDev(right, mean1, std1);
  const double gain = std1[0] > 0 ? std0[0] / std1[0] : 1.0;
  cv::Mat out;
  right.convertTo(out, CV_8U, gain, mean0[0] - gain * mean1[0]);
  return out;
}

}  // namespace

void StereoFrontend::Impl::trackTemporal(const std::vector<cv::Mat>& pyramid0,
                                         const FramePrediction* prediction, TrackFrame* frame,
                                         std::vector<cv::Point2f>* points,
                                         std::unordered_map<int64_t, cv::Point2f>* predicted_right,
                                         FrontendFrameStats* stats,
                                         std::vector<FlowCandidate>* candidates) {
  std::vector<bool> in_view;
  std::vector<double> scale;
  const std::vector<cv::Point2f> start = predictLeft(prediction, &in_view, &scale);
  std::vector<cv::Point2f> tracked = start;
  std::vector<bool> lk_ok;
  std::vector<bool> ok = trackForwardBackward(prev_pyramid, pyramid0, prev_points, &tracked, &lk_ok,
                                              options.pyramid_levels);
  if (prediction != nullptr) {
    retrackScaled(prev_pyramid, pyramid0, start, scale, in_view, &tracked, &ok);
  }
  std::vector<std::size_t> survivors;
  std::vector<Eigen::Vector2d> uv_new;
  for (std::size_t i = 0; i < ok.size(); ++i) {
    Eigen::Vector2d uv;
    if (in_view[i] && ok[i] && undistort(cam0, tracked[i], &uv)) {
      survivors.push_back(i);
      uv_new.push_back(uv);
    }
  }
  std::vector<bool> keep(survivors.size(), true);
  geometricCheck(survivors, uv_new, &keep, stats);
  std::vector<bool> kept(ok.size(), false);
  for (std::size_t k = 0; k < survivors.size(); ++k) {
    if (!keep[k]) continue;
    const std::size_t i = survivors[k];
    kept[i] = true;
    addKeypoint(tracked[i], prev_ids[i], uv_new[k], frame, points);
    // The stereo start of a continued point: its predicted position projected into cam1.
    const auto p = prev_depth_points.find(prev_ids[i]);
    if (p == prev_depth_points.end()) continue;
    ++stats->n_continued_depth;
    if (prediction == nullptr) continue;
    if (auto r = project(cam1, T_c1_c0 * (prediction->T_new_prev * p->second))) {
      (*predicted_right)[prev_ids[i]] = *r;
    }
  }
  if (candidates != nullptr) {
    for (std::size_t i = 0; i < ok.size(); ++i) {
      candidates->push_back({prev_ids[i], prev_points[i].x, prev_points[i].y, tracked[i].x,
                             tracked[i].y, in_view[i] && lk_ok[i], kept[i]});
    }
  }
}

void StereoFrontend::Impl::advance(int64_t t_ns, const FrontendFrameStats& stats,
                                   const TrackFrame& frame, std::vector<cv::Mat>&& pyramid0,
                                   std::vector<cv::Point2f>&& points) {
  if (stats.has_motion) {
    last_motion = stats.T_new_prev;
    last_motion_dt_s = 1e-9 * static_cast<double>(t_ns - prev_t_ns);
  } else {
    last_motion.reset();
  }
  prev_t_ns = t_ns;
  last_raw_left.clear();
  for (const cv::Point2f& p : points) last_raw_left.emplace_back(p.x, p.y);
  prev_pyramid = std::move(pyramid0);
  prev_points = std::move(points);
  prev_ids.clear();
  prev_uv.clear();
  for (const StereoObservation& obs : frame.observations) {
    prev_ids.push_back(obs.track_id);
    prev_uv.push_back(obs.uv0);
  }
}

TrackFrame StereoFrontend::process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                                   FrontendFrameStats* stats,
                                   std::vector<FlowCandidate>* candidates,
                                   const FramePrediction* prediction) {
  Impl& m = *impl_;
  const auto start = std::chrono::steady_clock::now();
  const std::clock_t cpu_start = std::clock();
  FrontendFrameStats frame_stats;
  std::vector<cv::Mat> pyramid0, pyramid1;
  const int max_level = m.options.pyramid_levels - 1;
  cv::buildOpticalFlowPyramid(left, pyramid0, m.window(), max_level, true);
  cv::buildOpticalFlowPyramid(matchedRight(left, right), pyramid1, m.window(), max_level, true);

  // 1–3. Prediction, temporal tracking and its checks.
  std::optional<FramePrediction> own;
  if (m.options.prediction == MotionPredictionSource::kNone) {
    prediction = nullptr;
  } else if (prediction == nullptr) {
    own = m.ownPrediction(t_ns);
    if (own) prediction = &*own;
  }
  TrackFrame frame;
  frame.t_ns = t_ns;
  std::vector<cv::Point2f> points;
  std::unordered_map<int64_t, cv::Point2f> predicted_right;
  if (!m.prev_points.empty()) {
    m.trackTemporal(pyramid0, prediction, &frame, &points, &predicted_right, &frame_stats,
                    candidates);
  }
  const int n_tracked = static_cast<int>(points.size());

  // 4. New keypoints in the empty cells.
  std::vector<cv::Point2f> detected;
  m.detect(pyramid0, points, &detected);
  for (const cv::Point2f& p : detected) {
    Eigen::Vector2d uv;
    if (m.undistort(m.cam0, p, &uv)) addKeypoint(p, m.next_id++, uv, &frame, &points);
  }

  // 5. Stereo matches left → right.
  m.matchStereo(pyramid0, pyramid1, points, predicted_right, &frame);
  m.advance(t_ns, frame_stats, frame, std::move(pyramid0), std::move(points));
  if (stats != nullptr) {
    frame_stats.t_ns = t_ns;
    frame_stats.n_features = static_cast<int>(frame.observations.size());
    frame_stats.n_tracked = n_tracked;
    frame_stats.n_new = frame_stats.n_features - n_tracked;
    for (const StereoObservation& obs : frame.observations) frame_stats.n_stereo += obs.has_right;
    frame_stats.t_frontend_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    frame_stats.cpu_frontend_s = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    *stats = frame_stats;
  }
  return frame;
}

}  // namespace marglab
