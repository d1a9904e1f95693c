#pragma once
// Stereo image folders of the original dataset layouts, and the sequence that goes with them.
//
//   EuRoC / TUM-VI (ASL):  <dir>/mav0/cam{0,1}/data.csv ("#timestamp [ns],filename" rows) naming
//                          <dir>/mav0/cam{0,1}/data/<filename> (or <dir> = mav0). Frames are the
//                          cam0 rows whose timestamp also has a cam1 row (a dropped right frame
//                          drops the stereo frame).
//   KITTI odometry:        <dir>/image_0/NNNNNN.png and image_1/NNNNNN.png, one per times.txt line
//                          (<dir> = dataset/sequences/NN).
// A folder "has images" when cam0's data/ (ASL) or image_0/ (KITTI) exists; every file a list
// names for a used frame must then exist (InputError naming it otherwise); cam1 rows without a
// cam0 row are ignored.
//
// Ground truth fallback (loadImageSequence): a user's image folder often lacks the ground truth
// or the IMU (e.g. the shipped euroc/V1_01_easy_images, which holds only the cameras). They are
// taken from the shipped sequence of the same recording, found by name (the folder's name
// without an "_images" or "_keyframes" suffix, e.g. V1_01_easy; TUM-VI "dataset-room1_512_16" → room1; KITTI
// "NN") or, for EuRoC / TUM-VI, by the first camera timestamp (epoch ns, unique per recording).
// Without any ground truth the sequence still loads (hasTrajectory() false).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/data/types.h"

namespace marglab {

struct StereoImageList {
  std::vector<int64_t> t_ns;
  std::vector<std::string> left, right;  // image paths, one per frame
  std::string source;                    // the list / folder the paths came from
  std::size_t unpaired_left = 0;         // cam0 frames without a cam1 frame at the same time
  std::size_t size() const { return t_ns.size(); }
};

// "" when every cam0 frame has its cam1 frame; else a note that says how many frames are dropped
// (a cam1/data.csv shorter than cam0's, or a timestamp off by 1 ns, is otherwise silent).
std::string unpairedFramesNote(const StereoImageList& list);

// The stereo images of a loaded sequence folder, or nullopt when the folder has none.
std::optional<StereoImageList> findStereoImages(const Sequence& sequence);

struct ImageSequence {
  Sequence sequence;  // with ground truth / IMU from the fallback where the folder has none
  std::optional<StereoImageList> images;
  std::string fallback;  // shipped sequence that supplied GT / IMU ("" when none was needed)
};

// loadSequence + findStereoImages + the fallback above. Throws InputError.
ImageSequence loadImageSequence(const std::string& name_or_path);

}  // namespace marglab
