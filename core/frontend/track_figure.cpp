#include "core/frontend/track_figure.h"

#include <fmt/core.h>

#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <unordered_map>

#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/frontend/image_file.h"
#include "core/frontend/track_source.h"
#include "core/sim/track_io.h"

namespace marglab {

namespace fs = std::filesystem;

namespace {

// The raw image resampled into the pinhole image: out(u, v) = raw(d(u, v)).
cv::Mat toPinhole(const cv::Mat& raw, const CameraModel<double>& cam) {
  cv::Mat map_x(raw.rows, raw.cols, CV_32FC1), map_y(raw.rows, raw.cols, CV_32FC1);
  for (int v = 0; v < raw.rows; ++v) {
    for (int u = 0; u < raw.cols; ++u) {
      const Eigen::Vector2d d = cam.distortPixel(Eigen::Vector2d(u, v));
      map_x.at<float>(v, u) = static_cast<float>(d.x());
      map_y.at<float>(v, u) = static_cast<float>(d.y());
    }
  }
  cv::Mat out;
  cv::remap(raw, out, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::cvtColor(out, out, cv::COLOR_GRAY2BGR);
  return out;
}

cv::Point2f point(const Eigen::Vector2d& uv, float dx = 0) {
  return {static_cast<float>(uv.x()) + dx, static_cast<float>(uv.y())};
}

void drawFrame(const TrackStream& stream, std::size_t k, const TrackFigureRequest& request,
               int width, cv::Mat* canvas) {
  const float dx = static_cast<float>(width);
  const std::size_t first = k >= static_cast<std::size_t>(request.history)
                                ? k - static_cast<std::size_t>(request.history)
                                : 0;
  // Positions of every track over the history window, oldest first.
  std::unordered_map<int64_t, std::vector<cv::Point2f>> path;
  for (std::size_t i = first; i <= k; ++i) {
    for (const StereoObservation& obs : stream.frames[i].observations) {
      path[obs.track_id].push_back(point(obs.uv0));
    }
  }
  int n = 0;
  for (const StereoObservation& obs : stream.frames[k].observations) {
    const std::vector<cv::Point2f>& p = path[obs.track_id];
    const bool continued = p.size() > 1;
    for (std::size_t i = 1; i < p.size(); ++i) {
      cv::line(*canvas, p[i - 1], p[i], cv::Scalar(0, 200, 0), 1, cv::LINE_AA);
    }
    cv::circle(*canvas, point(obs.uv0), 2,
               continued ? cv::Scalar(0, 255, 0) : cv::Scalar(0, 230, 255), -1, cv::LINE_AA);
    if (!obs.has_right) continue;
    cv::circle(*canvas, point(obs.uv1, dx), 2, cv::Scalar(255, 255, 0), -1, cv::LINE_AA);
    if (n++ % request.stereo_stride == 0) {
      cv::line(*canvas, point(obs.uv0), point(obs.uv1, dx), cv::Scalar(255, 160, 0), 1,
               cv::LINE_AA);
    }
  }
}

}  // namespace

std::string drawTrackFigure(const TrackFigureRequest& request) {
  const ImageSequence images = loadImageSequence(request.dataset);
  if (!images.images) {
    throw UsageError(fmt::format("--figure tracks needs a folder with images; {} has none",
                                 images.sequence.directory));
  }
  const StereoImageList& list = *images.images;
  if (request.frame < 0 || static_cast<std::size_t>(request.frame) >= list.size()) {
    throw UsageError(fmt::format("--frame {} outside the {} stereo frames of {}", request.frame,
                                 list.size(), request.dataset));
  }
  const std::size_t k = static_cast<std::size_t>(request.frame);
  TrackStream stream = request.tracks_file.empty()
                           ? trackImages(images, FrontendOptions{}, k + 1).stream
                           : readTrackFile(request.tracks_file);
  // The track file may start later (cut to the ground truth): find frame k by its timestamp.
  std::size_t index = stream.frames.size();
  for (std::size_t i = 0; i < stream.frames.size(); ++i) {
    if (stream.frames[i].t_ns == list.t_ns[k]) index = i;
  }
  if (index == stream.frames.size()) {
    throw InputError(request.tracks_file, 0,
                     fmt::format("no frame at t_ns {} (stereo frame {})", list.t_ns[k], k));
  }
  const Sequence& seq = images.sequence;
  const auto cam0 = cameraModelFromCalib<double>(seq.calib.cam0, seq.calib_source);
  const auto cam1 = cameraModelFromCalib<double>(seq.calib.cam1, seq.calib_source);
  const cv::Mat left =
      toPinhole(readGreyImage(list.left[k], seq.calib.cam0.width, seq.calib.cam0.height), cam0);
  const cv::Mat right =
      toPinhole(readGreyImage(list.right[k], seq.calib.cam1.width, seq.calib.cam1.height), cam1);
  cv::Mat canvas;
  cv::hconcat(left, right, canvas);
  drawFrame(stream, index, request, left.cols, &canvas);
  fs::create_directories(request.out_dir);
  std::string name = seq.name;
  for (char& c : name) c = c == '/' ? '-' : c;
  const std::string path =
      (fs::path(request.out_dir) / fmt::format("tracks_{}_{:04d}.png", name, k)).string();
  const std::vector<uint8_t> png = encodePng(canvas);
  writeFileAtomically(path,
                      std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  return path;
}

}  // namespace marglab
