#include "core/frontend/track_source.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "core/common/error.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/track_io.h"

namespace marglab {

namespace {

// Without ground truth: the body stays at the origin (a VO run starts at the identity).
class StillTrajectory : public TrajectoryFunction {
 public:
  StillTrajectory(int64_t start_ns, int64_t end_ns) : start_ns_(start_ns), end_ns_(end_ns) {}
  int64_t startTimeNs() const override { return start_ns_; }
  int64_t endTimeNs() const override { return end_ns_; }
  TrajectorySample evaluate(int64_t) const override { return {}; }

 private:
  int64_t start_ns_, end_ns_;
};

// The estimator's frames: those inside the ground truth's span, then the first max_frames.
void cutToEstimatorFrames(const Sequence& sequence, int max_frames, TrackStream* stream) {
  auto& frames = stream->frames;
  if (sequence.hasTrajectory()) {
    const int64_t t0 = sequence.gt.t_ns.front(), t1 = sequence.gt.t_ns.back();
    frames.erase(std::remove_if(frames.begin(), frames.end(),
                                [&](const TrackFrame& f) { return f.t_ns < t0 || f.t_ns > t1; }),
                 frames.end());
  }
  if (max_frames > 0 && frames.size() > static_cast<std::size_t>(max_frames)) {
    frames.resize(static_cast<std::size_t>(max_frames));
  }
  if (frames.empty()) {
    throw InputError(sequence.directory, 0,
                     "no camera frame lies inside the trajectory (nothing for the estimator)");
  }
}

void addTrajectory(TrackSource* source) {
  const Sequence& seq = source->sequence;
  source->has_ground_truth = seq.hasTrajectory();
  if (source->has_ground_truth) {
    source->trajectory = std::make_unique<TrajectorySpline>(TrajectorySpline::fromSequence(seq));
  } else {
    const int64_t t0 = seq.cam_t_ns.empty() ? 0 : seq.cam_t_ns.front();
    const int64_t t1 = seq.cam_t_ns.empty() ? 0 : seq.cam_t_ns.back();
    source->trajectory = std::make_unique<StillTrajectory>(t0, t1);
  }
}

void simulate(const TrackSourceOptions& options, TrackSource* source) {
  const Sequence& seq = source->sequence;
  if (!seq.hasTrajectory()) {
    throw InputError(seq.directory, 0,
                     fmt::format("sequence {} has no trajectory to simulate from (only camera "
                                 "timestamps); use its images (--frontend images) or a track file",
                                 seq.name));
  }
  SimulationOptions simulation = defaultSimulationOptions(seq, options.seed);
  if (options.max_frames > 0) simulation.tracker.max_frames = options.max_frames;
  std::string profile = toString(options.sim_profile);
  if (options.sim_profile != SimProfile::kIdeal) {
    const std::string path = realisticProfilePath(seq.kind, options.sim_profile);
    applyRealisticProfile(readRealisticProfile(path), &simulation.tracker);
    profile += " (" + path + ")";
  }
  applySimOverrides(options.sim_overrides, &simulation.tracker);
  applySimOverrides(options.sim_overrides, &simulation.world);
  if (options.sim_overrides.any()) {
    profile += fmt::format(", grid {:g} px, loss {:g}, stereo failure {:g}, facades {:g}-{:g} m",
                           simulation.tracker.grid_cell_px, simulation.tracker.loss_probability,
                           simulation.tracker.stereo_failure_probability,
                           simulation.world.facade_offset_min, simulation.world.facade_offset_max);
  }
  source->stream = simulateSequence(seq, *source->trajectory, simulation);
  source->stats = streamFrontendStats(source->stream);
  source->frontend = "simulated";
  source->provenance.emplace_back("measurements", "simulated stereo tracks, undistorted pinhole");
  source->provenance.emplace_back("sim_profile", profile);
}

}  // namespace

ImageTracker::ImageTracker(const ImageSequence& images, const FrontendOptions& options)
    : list_(images.images ? *images.images : StereoImageList{}),
      width0_(images.sequence.calib.cam0.width),
      height0_(images.sequence.calib.cam0.height),
      width1_(images.sequence.calib.cam1.width),
      height1_(images.sequence.calib.cam1.height),
      options_(defaultFrontendOptions(images.sequence, options)),
      frontend_(images.sequence.calib, options_, images.sequence.calib_source) {
  if (!images.images) {
    throw UsageError(fmt::format("{} has no images (expected mav0/cam0/data/ or image_0/)",
                                 images.sequence.directory));
  }
}

TrackFrame ImageTracker::trackNext(const FramePrediction* prediction) {
  const std::size_t i = next_++;
  const auto start = std::chrono::steady_clock::now();
  const cv::Mat left = readGreyImage(list_.left[i], width0_, height0_);
  const cv::Mat right = readGreyImage(list_.right[i], width1_, height1_);
  t_decode_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  FrontendFrameStats stats;
  TrackFrame frame = frontend_.process(list_.t_ns[i], left, right, &stats, nullptr, prediction);
  stats_.push_back(stats);
  return frame;
}

ImageTracking trackImages(const ImageSequence& images, const FrontendOptions& options,
                          std::size_t max_images) {
  ImageTracker tracker(images, options);
  const std::size_t n = max_images > 0 ? std::min(max_images, tracker.size()) : tracker.size();
  ImageTracking out;
  out.stream.sequence = images.sequence.name;
  while (tracker.next() < n) out.stream.frames.push_back(tracker.trackNext());
  out.stats = tracker.stats();
  out.t_decode_s = tracker.decodeSeconds();
  return out;
}

int64_t TrackSource::frameTimeNs(std::size_t k) const {
  return images ? images->timeNs(first_image + k) : stream.frames.at(k).t_ns;
}

TrackFrame TrackSource::frame(std::size_t k, const FramePrediction* prediction) {
  if (!images) return stream.frames.at(k);
  if (images->next() != first_image + k) {
    throw std::logic_error("TrackSource::frame: image frames are tracked in order");
  }
  return images->trackNext(prediction);
}

const std::vector<FrontendFrameStats>& TrackSource::frontendStats() const {
  return images ? images->stats() : stats;
}

namespace {

// The images path of obtainTracks: the images before the estimator's first frame are tracked now
// (the tracks are mature when the estimator starts); its frames are tracked as it asks for them.
void startImages(const TrackSourceOptions& options, const ImageSequence& folder,
                 TrackSource* source) {
  source->images = std::make_unique<ImageTracker>(folder, options.frontend_options);
  const Sequence& seq = source->sequence;
  const std::vector<int64_t>& t = folder.images->t_ns;
  std::size_t first = 0, last = t.size();
  if (seq.hasTrajectory()) {
    first = static_cast<std::size_t>(std::lower_bound(t.begin(), t.end(), seq.gt.t_ns.front()) -
                                     t.begin());
    last = static_cast<std::size_t>(std::upper_bound(t.begin(), t.end(), seq.gt.t_ns.back()) -
                                    t.begin());
  }
  if (options.max_frames > 0) {
    last = std::min(last, first + static_cast<std::size_t>(options.max_frames));
  }
  // Tracked before the check below, so that a bad image among them is named first.
  while (source->images->next() < std::min(first, t.size())) source->images->trackNext();
  if (first >= last) {
    throw InputError(seq.directory, 0,
                     "no camera frame lies inside the trajectory (nothing for the estimator)");
  }
  source->first_image = first;
  source->n_frames = last - first;
  source->stream.sequence = seq.name;
  source->frontend = "images";
  source->provenance.emplace_back(
      "measurements", "stereo optical-flow front-end on the images, undistorted pinhole");
  source->provenance.emplace_back("images", folder.images->source);
  source->provenance.emplace_back("frontend_prediction",
                                  toString(source->images->options().prediction));
}

}  // namespace

TrackSource obtainTracks(const TrackSourceOptions& options, const ImageSequence& images,
                         std::optional<TrackStream> tracks) {
  TrackSource source;
  source.sequence = images.sequence;
  if (!images.fallback.empty()) {
    source.provenance.emplace_back("fallback_sequence", images.fallback);
  }
  addTrajectory(&source);
  if (!options.tracks_file.empty()) {
    source.stream = tracks ? std::move(*tracks) : readTrackFile(options.tracks_file);
    cutToEstimatorFrames(source.sequence, options.max_frames, &source.stream);
    source.stats = streamFrontendStats(source.stream);
    source.n_frames = source.stream.frames.size();
    source.frontend = "tracks";
    source.provenance.emplace_back("measurements", "track file " + options.tracks_file);
    return source;
  }
  const bool use_images = options.frontend == FrontendKind::kImages ||
                          (options.frontend == FrontendKind::kAuto && images.images.has_value());
  if (use_images) {
    startImages(options, images, &source);
  } else {
    simulate(options, &source);
    source.n_frames = source.stream.frames.size();
  }
  return source;
}

std::vector<FrontendFrameStats> streamFrontendStats(const TrackStream& stream) {
  std::vector<FrontendFrameStats> rows;
  std::unordered_set<int64_t> previous;
  for (const TrackFrame& frame : stream.frames) {
    FrontendFrameStats s;
    s.t_ns = frame.t_ns;  // t_frontend_s keeps its default, NaN: not measured
    std::unordered_set<int64_t> current;
    for (const StereoObservation& obs : frame.observations) {
      ++s.n_features;
      if (previous.count(obs.track_id) != 0) ++s.n_tracked;
      if (obs.has_right) ++s.n_stereo;
      current.insert(obs.track_id);
    }
    s.n_new = s.n_features - s.n_tracked;
    rows.push_back(s);
    previous = std::move(current);
  }
  return rows;
}

std::vector<FrontendRecord> frontendRecords(const std::vector<FrontendFrameStats>& stats) {
  return {stats.begin(), stats.end()};
}

double medianTrackLength(const TrackStream& stream) {
  std::unordered_map<int64_t, int> length;
  for (const TrackFrame& frame : stream.frames) {
    for (const StereoObservation& obs : frame.observations) ++length[obs.track_id];
  }
  std::vector<double> values;
  for (const auto& [id, n] : length) values.push_back(n);
  return distributionOf(values).median;
}

std::string frontendSummary(const std::string& frontend,
                            const std::vector<FrontendFrameStats>& stats) {
  std::vector<double> features, tracked;
  double stereo = 0, total = 0, time = 0;
  for (const FrontendFrameStats& s : stats) {
    features.push_back(s.n_features);
    tracked.push_back(s.n_tracked);
    stereo += s.n_stereo;
    total += s.n_features;
    time += s.t_frontend_s;
  }
  const double n = static_cast<double>(std::max<std::size_t>(stats.size(), 1));
  std::string text =
      fmt::format("{}: {} frames, {:.0f} features/frame (median), {:.0f} tracked, stereo {:.0f} %",
                  frontend, stats.size(), distributionOf(features).median,
                  distributionOf(tracked).median, 100.0 * stereo / std::max(total, 1.0));
  if (std::isfinite(time)) {
    text += fmt::format(", {:.2f} ms/frame ({:.0f} frames/s)", 1e3 * time / n, n / time);
  }
  return text;
}

}  // namespace marglab
