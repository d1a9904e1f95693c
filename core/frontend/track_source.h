#pragma once
// Where a run's feature tracks come from (`marglab run --frontend`, `--tracks`): the one function
// the run pipeline calls to obtain the sequence, its trajectory and the TrackStream the estimator
// consumes. The estimator's code path is the same for all three sources.
//
//   simulated  stereo tracks simulated along the ground truth (core/sim/feature_tracker.h);
//   images     the stereo optical-flow front-end (optical_flow.h) on the folder's images;
//   tracks     a track file (core/sim/track_io.h) written by `marglab datasets track`,
//              `marglab datasets simulate` or any external front-end.
//   auto       images where the dataset folder has them, simulated otherwise.
//
// Frames. The estimator starts from the ground-truth state at its first frame, so it runs on the
// frames inside the ground truth's time span: images are tracked from the first image on (the
// tracks are mature when the estimator starts), and the stream is cut to the frames within the
// ground truth, then to max_frames. Images and tracks are cut by the same function, so a track
// file written from the images gives the estimator exactly the frames of the images run. Without
// any ground truth (and no shipped sequence to fall back on, image_folder.h) every frame is used
// and the trajectory is a still pose at the origin (VO only: the run starts at the identity and
// reports no ATE).
//
// Images are tracked frame by frame (ImageTracker), so that the run can hand the front-end the
// estimator's prediction of each frame (optical_flow.h, "Prediction"): obtainTracks tracks the
// images before the estimator's first frame at once (with the tracker's own prediction), and the
// estimator's frames are tracked when the run asks for them (TrackSource::frame). A track file
// written by `datasets track` holds the tracks of prediction "tracker" (no estimator there).

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/common/enum_names.h"
#include "core/data/tracks.h"
#include "core/data/types.h"
#include "core/frontend/image_folder.h"
#include "core/frontend/optical_flow.h"
#include "core/io/results_file.h"
#include "core/sim/sim_profile.h"
#include "core/sim/trajectory_spline.h"

namespace marglab {

enum class FrontendKind { kAuto, kImages, kSimulated };
inline constexpr EnumNames<FrontendKind, 3> kFrontendKindNames{
    {{FrontendKind::kAuto, "auto"},
     {FrontendKind::kImages, "images"},
     {FrontendKind::kSimulated, "simulated"}}};

struct TrackSourceOptions {
  std::string dataset;
  FrontendKind frontend = FrontendKind::kAuto;
  std::string tracks_file;  // non-empty: the tracks come from this file (frontend "tracks")
  int max_frames = 0;       // estimator frames; 0: all
  std::uint64_t seed = 1;   // simulation seed
  SimProfile sim_profile = SimProfile::kIdeal;  // the simulation's measurement model
  SimOverrides sim_overrides;                   // single settings replaced on top of it
  FrontendOptions frontend_options;  // [frontend]; dataset-default sentinels resolved here
};

// The image front-end one stereo frame at a time, in order.
class ImageTracker {
 public:
  // Throws UsageError when the folder has no images.
  ImageTracker(const ImageSequence& images, const FrontendOptions& options);
  std::size_t size() const { return list_.size(); }
  std::size_t next() const { return next_; }  // the image trackNext() decodes
  int64_t timeNs(std::size_t i) const { return list_.t_ns[i]; }
  const FrontendOptions& options() const { return options_; }
  // Decodes and tracks image next() (InputError naming a missing or undecodable image).
  TrackFrame trackNext(const FramePrediction* prediction = nullptr);
  const std::vector<FrontendFrameStats>& stats() const { return stats_; }
  double decodeSeconds() const { return t_decode_s_; }

 private:
  StereoImageList list_;
  int width0_, height0_, width1_, height1_;
  FrontendOptions options_;
  StereoFrontend frontend_;
  std::vector<FrontendFrameStats> stats_;
  std::size_t next_ = 0;
  double t_decode_s_ = 0;
};

struct TrackSource {
  Sequence sequence;  // with the shipped fallback's ground truth / IMU where used
  std::unique_ptr<TrajectoryFunction> trajectory;
  bool has_ground_truth = false;
  TrackStream stream;                     // the estimator's frames (images: those tracked so far)
  std::string frontend;                   // "images" | "simulated" | "tracks"
  std::vector<FrontendFrameStats> stats;  // /frontend rows: every frame the source produced
  std::vector<std::pair<std::string, std::string>> provenance;  // results-file root attributes
  std::unique_ptr<ImageTracker> images;  // frontend "images": the estimator's frames to come
  std::size_t first_image = 0;           // the image of the estimator's frame 0
  std::size_t n_frames = 0;              // the estimator's frames

  int64_t frameTimeNs(std::size_t k) const;
  // The estimator's frame k, k = 0, 1, … in order: from the stream, or (images) tracked now,
  // starting from `prediction` where given.
  TrackFrame frame(std::size_t k, const FramePrediction* prediction = nullptr);
  // /frontend rows of every frame produced so far.
  const std::vector<FrontendFrameStats>& frontendStats() const;
};

// Throws InputError (bad or missing files, images of the wrong size, a sequence without ground
// truth for the simulation) and UsageError (--frontend images on a folder without images).
// `images`: the dataset as loaded (loadImageSequence(options.dataset)); `tracks`: the stream of
// options.tracks_file where the caller has read it already (else it is read here).
TrackSource obtainTracks(const TrackSourceOptions& options, const ImageSequence& images,
                         std::optional<TrackStream> tracks = std::nullopt);

// The front-end on the first max_images stereo frames of a folder (0: all), with the tracker's own
// prediction (options.prediction "estimator" falls back to it: there is no estimator here).
struct ImageTracking {
  TrackStream stream;
  std::vector<FrontendFrameStats> stats;
  double t_decode_s = 0;  // PNG decoding, not part of t_frontend_s
};
ImageTracking trackImages(const ImageSequence& images, const FrontendOptions& options,
                          std::size_t max_images = 0);

// /frontend rows recomputed from a stream (no timing: t_frontend_s = NaN).
std::vector<FrontendFrameStats> streamFrontendStats(const TrackStream& stream);

// "front-end images: 95 frames, 152 features/frame (median), 138 tracked, track length median
// 9, stereo 93 %, 1.9 ms/frame (520 frames/s)".
std::string frontendSummary(const std::string& frontend,
                            const std::vector<FrontendFrameStats>& stats);

// The results file's /frontend rows: the FrontendRecord part of each.
std::vector<FrontendRecord> frontendRecords(const std::vector<FrontendFrameStats>& stats);

// Median number of frames a track id is observed in.
double medianTrackLength(const TrackStream& stream);

}  // namespace marglab
