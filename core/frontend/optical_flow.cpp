#include "core/frontend/optical_flow.h"

#include <fmt/core.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <unordered_map>

#include "core/common/error.h"
#include "core/frontend/image_file.h"
#include "core/geometry/so3.h"

namespace marglab {

FrontendOptions defaultFrontendOptions(const Sequence& sequence) {
  FrontendOptions options;
  options.grid_cell_px = static_cast<int>(std::lround(sequence.defaults.grid_cell_px));
  return options;
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

struct StereoFrontend::Impl {
  FrontendOptions options;
  CameraModel<double> cam0, cam1;
  Eigen::Matrix3d E;  // essential matrix [t̂]× R of T_c0_c1, unit translation
  Eigen::Matrix3d R_c1_c0;
  Eigen::Vector3d t_c1_c0;
  double baseline = 0;
  int width = 0, height = 0;
  std::vector<cv::Mat> prev_pyramid;
  std::vector<cv::Point2f> prev_points;  // raw left keypoints of the previous frame
  std::vector<int64_t> prev_ids;
  std::unordered_map<int64_t, cv::Point2f> prev_disparity;  // raw right − raw left, last frame
  std::unordered_map<int64_t, int> unmatched;  // tracks without a match: frames since their last
  std::vector<Eigen::Vector2d> last_raw_left;
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
    const Eigen::Vector3d b0 =
        Eigen::Vector3d((uv0.x() - cam0.cx) / cam0.fx, (uv0.y() - cam0.cy) / cam0.fy, 1)
            .normalized();
    const Eigen::Vector3d b1 =
        Eigen::Vector3d((uv1.x() - cam1.cx) / cam1.fx, (uv1.y() - cam1.cy) / cam1.fy, 1)
            .normalized();
    return std::abs(b0.dot(E * b1)) <= options.epipolar_max;
  }

  std::vector<bool> trackForwardBackward(const std::vector<cv::Mat>& from,
                                         const std::vector<cv::Mat>& to,
                                         const std::vector<cv::Point2f>& points,
                                         std::vector<cv::Point2f>* tracked,
                                         std::vector<bool>* lk_ok) const;
  void detect(const cv::Mat& image, const std::vector<cv::Point2f>& occupied,
              std::vector<cv::Point2f>* found) const;
  cv::Point2f disparityGuess(const Eigen::Vector2d& uv0, double disparity_px) const;
  void matchStereo(const std::vector<cv::Mat>& pyramid0, const std::vector<cv::Mat>& pyramid1,
                   const std::vector<cv::Point2f>& points, TrackFrame* frame);
};

// LK from `from` to `to` starting at *tracked (the initial guesses), then back; ok[i] when both
// converge, the result is inside the image and the round trip returns within
// fb_max_px.
std::vector<bool> StereoFrontend::Impl::trackForwardBackward(const std::vector<cv::Mat>& from,
                                                             const std::vector<cv::Mat>& to,
                                                             const std::vector<cv::Point2f>& points,
                                                             std::vector<cv::Point2f>* tracked,
                                                             std::vector<bool>* lk_ok) const {
  std::vector<bool> ok(points.size(), false);
  if (lk_ok != nullptr) lk_ok->assign(points.size(), false);
  if (points.empty()) return ok;
  const int max_level = options.pyramid_levels - 1;
  std::vector<uchar> status, back_status;
  std::vector<float> error;
  const std::vector<cv::Point2f> start = *tracked;
  cv::calcOpticalFlowPyrLK(from, to, points, *tracked, status, error, window(), max_level,
                           criteria(), cv::OPTFLOW_USE_INITIAL_FLOW);
  // The backward pass gets the same prior as the forward one, inverted: it starts at the forward
  // result minus the forward start's offset (temporal: no offset; stereo: the disparity guess).
  std::vector<cv::Point2f> back(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) back[i] = (*tracked)[i] - (start[i] - points[i]);
  cv::calcOpticalFlowPyrLK(to, from, *tracked, back, back_status, error, window(), max_level,
                           criteria(), cv::OPTFLOW_USE_INITIAL_FLOW);
  const double fb2 = options.fb_max_px * options.fb_max_px;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const bool forward = status[i] != 0 && inside((*tracked)[i]);
    if (lk_ok != nullptr) (*lk_ok)[i] = forward;
    const cv::Point2f d = back[i] - points[i];
    ok[i] = forward && back_status[i] != 0 && d.dot(d) <= fb2;
  }
  return ok;
}

// Shi–Tomasi maximum in each grid cell that holds no occupied point.
void StereoFrontend::Impl::detect(const cv::Mat& image, const std::vector<cv::Point2f>& occupied,
                                  std::vector<cv::Point2f>* found) const {
  const int c = options.grid_cell_px;
  const int nx = (width + c - 1) / c, ny = (height + c - 1) / c;
  std::vector<char> full(static_cast<std::size_t>(nx * ny), 0);
  for (const cv::Point2f& p : occupied) {
    const int i = static_cast<int>(p.x) / c, j = static_cast<int>(p.y) / c;
    if (i >= 0 && i < nx && j >= 0 && j < ny) full[static_cast<std::size_t>(j * nx + i)] = 1;
  }
  const int b = options.border_px, pad = options.corner_block_px;
  const cv::Rect valid(b, b, width - 2 * b, height - 2 * b);
  cv::Mat response;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      if (full[static_cast<std::size_t>(j * nx + i)]) continue;
      const cv::Rect cell = cv::Rect(i * c, j * c, c, c) & valid;
      if (cell.empty()) continue;
      // Padding so that the structure tensor at the cell's edge sees real neighbours.
      const cv::Rect padded =
          cv::Rect(cell.x - pad, cell.y - pad, cell.width + 2 * pad, cell.height + 2 * pad) &
          cv::Rect(0, 0, width, height);
      cv::cornerMinEigenVal(image(padded), response, options.corner_block_px, 3);
      const cv::Mat inner = response(cell - padded.tl());
      double best = 0;
      cv::Point at;
      cv::minMaxLoc(inner, nullptr, &best, nullptr, &at);
      if (best >= options.min_eigen) {
        found->emplace_back(static_cast<float>(cell.x + at.x), static_cast<float>(cell.y + at.y));
      }
    }
  }
}

// The raw right pixel of the left keypoint uv0 (pinhole) if its stereo disparity were d pixels:
// depth z = f b / d along the left ray, mapped into cam1 (d = 0: the same raw pixel).
cv::Point2f StereoFrontend::Impl::disparityGuess(const Eigen::Vector2d& uv0,
                                                 double disparity_px) const {
  if (disparity_px <= 0) {
    const Eigen::Vector2d raw = cam0.distortPixel(uv0);
    return {static_cast<float>(raw.x()), static_cast<float>(raw.y())};
  }
  const double z = cam0.fx * baseline / disparity_px;
  const Eigen::Vector3d p_c0(z * (uv0.x() - cam0.cx) / cam0.fx, z * (uv0.y() - cam0.cy) / cam0.fy,
                             z);
  const Eigen::Vector3d p_c1 = R_c1_c0 * p_c0 + t_c1_c0;
  const Eigen::Vector2d uv1(cam1.fx * p_c1.x() / p_c1.z() + cam1.cx,
                            cam1.fy * p_c1.y() / p_c1.z() + cam1.cy);
  const Eigen::Vector2d raw = cam1.distortPixel(uv1);
  return {static_cast<float>(raw.x()), static_cast<float>(raw.y())};
}

// Left → right matches. LK converges only within a few pixels of its start on the coarsest
// level, and near points (EuRoC's floor at take-off) have disparities of 50+ px, so each keypoint
// is tried from a sequence of starts until one passes the forward–backward and epipolar checks:
// its track's disparity in the previous frame (if it had a match), then the disparity guesses.
// A track that found no match tries one guess per frame in turn (all within a few frames): most
// such points are out of the right view or occluded, and retrying every guess in every frame
// would cost most of the front-end's time.
void StereoFrontend::Impl::matchStereo(const std::vector<cv::Mat>& pyramid0,
                                       const std::vector<cv::Mat>& pyramid1,
                                       const std::vector<cv::Point2f>& points, TrackFrame* frame) {
  std::unordered_map<int64_t, cv::Point2f> disparity;
  std::vector<std::size_t> pending(points.size());
  for (std::size_t i = 0; i < pending.size(); ++i) pending[i] = i;
  const std::size_t rounds = options.stereo_disparity_guesses_px.size() + 1;
  for (std::size_t round = 0; round < rounds && !pending.empty(); ++round) {
    std::vector<cv::Point2f> from, guess;
    std::vector<std::size_t> tried;
    for (const std::size_t i : pending) {
      const StereoObservation& obs = frame->observations[i];
      const auto prev = prev_disparity.find(obs.track_id);
      if (round == 0 && prev == prev_disparity.end()) continue;
      const auto miss = unmatched.find(obs.track_id);
      if (round > 0 && miss != unmatched.end() &&
          static_cast<std::size_t>(miss->second) % (rounds - 1) != round - 1) {
        continue;
      }
      from.push_back(points[i]);
      guess.push_back(
          round == 0 ? points[i] + prev->second
                     : disparityGuess(obs.uv0, options.stereo_disparity_guesses_px[round - 1]));
      tried.push_back(i);
    }
    const std::vector<bool> ok = trackForwardBackward(pyramid0, pyramid1, from, &guess, nullptr);
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
  const Eigen::Matrix3d R_c0_c1 = calib.cam0.R_b_c.transpose() * calib.cam1.R_b_c;
  const Eigen::Vector3d t_c0_c1 =
      calib.cam0.R_b_c.transpose() * (calib.cam1.t_b_c - calib.cam0.t_b_c);
  m.E = hat<double>(Eigen::Vector3d(t_c0_c1.normalized())) * R_c0_c1;
  m.R_c1_c0 = R_c0_c1.transpose();
  m.t_c1_c0 = -(R_c0_c1.transpose() * t_c0_c1);
  m.baseline = t_c0_c1.norm();
}

StereoFrontend::~StereoFrontend() = default;
StereoFrontend::StereoFrontend(StereoFrontend&&) noexcept = default;
StereoFrontend& StereoFrontend::operator=(StereoFrontend&&) noexcept = default;

const std::vector<Eigen::Vector2d>& StereoFrontend::lastRawLeft() const {
  return impl_->last_raw_left;
}

TrackFrame StereoFrontend::process(int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                                   FrontendFrameStats* stats,
                                   std::vector<FlowCandidate>* candidates) {
  Impl& m = *impl_;
  const auto start = std::chrono::steady_clock::now();
  const std::clock_t cpu_start = std::clock();
  std::vector<cv::Mat> pyramid0, pyramid1;
  cv::buildOpticalFlowPyramid(left, pyramid0, m.window(), m.options.pyramid_levels - 1, true);
  // The two cameras' exposures differ (EuRoC: mean grey 146 vs 131) and LK assumes equal
  // brightness: the right image is mapped to the left's mean and contrast for the stereo match.
  cv::Scalar mean0, std0, mean1, std1;
  cv::meanStdDev(left, mean0, std0);
  cv::meanStdDev(right, mean1, std1);
  const double gain = std1[0] > 0 ? std0[0] / std1[0] : 1.0;
  cv::Mat right_matched;
  right.convertTo(right_matched, CV_8U, gain, mean0[0] - gain * mean1[0]);
  cv::buildOpticalFlowPyramid(right_matched, pyramid1, m.window(), m.options.pyramid_levels - 1,
                              true);

  // 1. Temporal tracking with the forward–backward check.
  TrackFrame frame;
  frame.t_ns = t_ns;
  std::vector<cv::Point2f> points;
  auto add = [&](const cv::Point2f& p, int64_t id, const Eigen::Vector2d& uv) {
    points.push_back(p);
    StereoObservation obs;
    obs.track_id = id;
    obs.uv0 = uv;
    frame.observations.push_back(obs);
  };
  if (!m.prev_points.empty()) {
    std::vector<cv::Point2f> tracked = m.prev_points;  // initial guess: no motion
    std::vector<bool> lk_ok;
    const std::vector<bool> ok =
        m.trackForwardBackward(m.prev_pyramid, pyramid0, m.prev_points, &tracked, &lk_ok);
    for (std::size_t i = 0; i < ok.size(); ++i) {
      Eigen::Vector2d uv;
      const bool kept = ok[i] && m.undistort(m.cam0, tracked[i], &uv);
      if (candidates != nullptr) {
        candidates->push_back({m.prev_ids[i], m.prev_points[i].x, m.prev_points[i].y, tracked[i].x,
                               tracked[i].y, lk_ok[i], kept});
      }
      if (kept) add(tracked[i], m.prev_ids[i], uv);
    }
  }
  const int n_tracked = static_cast<int>(points.size());

  // 2. New keypoints in the empty cells.
  std::vector<cv::Point2f> detected;
  m.detect(left, points, &detected);
  for (const cv::Point2f& p : detected) {
    Eigen::Vector2d uv;
    if (m.undistort(m.cam0, p, &uv)) add(p, m.next_id++, uv);
  }

  // 3. Stereo matches left → right: forward–backward and epipolar checks.
  m.matchStereo(pyramid0, pyramid1, points, &frame);

  m.last_raw_left.clear();
  for (const cv::Point2f& p : points) m.last_raw_left.emplace_back(p.x, p.y);
  m.prev_pyramid = std::move(pyramid0);
  m.prev_points = std::move(points);
  m.prev_ids.clear();
  for (const StereoObservation& obs : frame.observations) m.prev_ids.push_back(obs.track_id);
  if (stats != nullptr) {
    stats->t_ns = t_ns;
    stats->n_features = static_cast<int>(frame.observations.size());
    stats->n_tracked = n_tracked;
    stats->n_new = stats->n_features - n_tracked;
    stats->n_stereo = 0;
    for (const StereoObservation& obs : frame.observations) stats->n_stereo += obs.has_right;
    stats->t_frontend_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    stats->cpu_frontend_s = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
  }
  return frame;
}

}  // namespace marglab
