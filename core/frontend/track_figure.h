#pragma once
// `marglab plot --figure tracks`: one stereo frame with its feature tracks, the first thing to
// look at when judging a front-end.
//
// The picture shows the left and right images side by side, both resampled into the pinhole
// image the estimator uses (pixel (u, v) of the pinhole image takes the raw image's value at
// d(u, v), camera_model.h, bilinear), so that the tracks — which are in pinhole coordinates —
// sit exactly on the image content:
//   left:  each observation of the frame with its positions in the previous frames of the same
//          track (up to `history` frames: the flow), green if continued, yellow if new;
//   right: the stereo match of each observation with a right keypoint (cyan), joined to its left
//          keypoint by a thin line across the two images (every `stereo_stride`-th match, so the
//          lines stay readable).
// The tracks come from the front-end on the folder's images, or from a track file.

#include <string>

namespace marglab {

struct TrackFigureRequest {
  std::string dataset;      // a folder with images, or a shipped name (euroc/V1_01_easy_images)
  std::string tracks_file;  // optional: draw these tracks instead of running the front-end
  int frame = 40;           // index into the folder's stereo frames
  int history = 10;
  int stereo_stride = 4;
  std::string out_dir = "notebooks-out/tracks";
};

// Writes <out_dir>/tracks_<sequence>_<frame>.png and returns its path. Throws InputError /
// UsageError.
std::string drawTrackFigure(const TrackFigureRequest& request);

}  // namespace marglab
