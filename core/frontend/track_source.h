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

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/data/types.h"
#include "core/frontend/image_folder.h"
#include "core/frontend/optical_flow.h"
#include "core/io/results_file.h"
#include "core/sim/sim_profile.h"
#include "core/sim/tracks.h"
#include "core/sim/trajectory_spline.h"

namespace marglab {

enum class FrontendKind { kAuto, kImages, kSimulated };
// "auto" | "images" | "simulated" → kind; false for anything else.
bool parseFrontendKind(const std::string& text, FrontendKind* kind);

struct TrackSourceOptions {
  std::string dataset;
  FrontendKind frontend = FrontendKind::kAuto;
  std::string tracks_file;  // non-empty: the tracks come from this file (frontend "tracks")
  int max_frames = 0;       // estimator frames; 0: all
  std::uint64_t seed = 1;   // simulation seed
  SimProfile sim_profile = SimProfile::kIdeal;  // the simulation's measurement model
};

struct TrackSource {
  Sequence sequence;  // with the shipped fallback's ground truth / IMU where used
  std::unique_ptr<TrajectoryFunction> trajectory;
  bool has_ground_truth = false;
  TrackStream stream;                     // the estimator's frames
  std::string frontend;                   // "images" | "simulated" | "tracks"
  std::vector<FrontendFrameStats> stats;  // /frontend rows: every frame the source produced
  std::vector<std::pair<std::string, std::string>> provenance;  // results-file root attributes
};

// Throws InputError (bad or missing files, images of the wrong size, a sequence without ground
// truth for the simulation) and UsageError (--frontend images on a folder without images).
TrackSource obtainTracks(const TrackSourceOptions& options);

// The front-end on the first max_images stereo frames of a folder (0: all).
struct ImageTracking {
  TrackStream stream;
  std::vector<FrontendFrameStats> stats;
  double t_decode_s = 0;  // PNG decoding, not part of t_frontend_s
};
ImageTracking trackImages(const ImageSequence& images, std::size_t max_images = 0);

// /frontend rows recomputed from a stream (no timing: t_frontend_s = NaN).
std::vector<FrontendFrameStats> streamFrontendStats(const TrackStream& stream);

// "front-end images: 95 frames, 152 features/frame (median), 138 tracked, track length median
// 9, stereo 93 %, 1.9 ms/frame (520 frames/s)".
std::string frontendSummary(const std::string& frontend,
                            const std::vector<FrontendFrameStats>& stats);

// The results file's /frontend rows.
std::vector<FrontendRecord> frontendRecords(const std::vector<FrontendFrameStats>& stats);

// Median number of frames a track id is observed in.
double medianTrackLength(const TrackStream& stream);

}  // namespace marglab
