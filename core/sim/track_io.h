#pragma once
// Track files: a TrackStream on disk, so that the estimator can be fed by the simulator or by a
// real front-end (e.g. KLT on real images). Two formats, chosen by the file name on writing
// (".h5" / ".hdf5": HDF5, anything else: text) and by content on reading (HDF5 signature).
// Pixels are in the undistorted pinhole image of the sequence's calibration (fx, fy, cx, cy;
// pixel centres at integer coordinates), as the simulator measures (feature_tracker.h).
//
// HDF5 ("marglab-tracks", version 1):
//   /                         attributes format = "marglab-tracks", format_version = 1,
//                             sequence (string), seed (int64; the uint64 seed's bits)
//   /frames/t_ns              int64 [M]      cam0 timestamps, strictly increasing
//   /observations/offsets     int64 [M+1]    frame i owns rows offsets[i] .. offsets[i+1]−1,
//                                            offsets[0] = 0, offsets[M] = K, non-decreasing
//   /observations/track_id    int64 [K]      ≥ 0, unique within a frame
//   /observations/u0, v0      f64 [K]        cam0 pixel, finite
//   /observations/has_right   uint8 [K]      0/1
//   /observations/u1, v1      f64 [K]        cam1 pixel; NaN where has_right = 0
//   /observations/landmark_id int64 [K]      simulation ground truth, −1 if unknown
//   /observations/is_outlier  uint8 [K]      simulation ground truth, 0 if unknown
//   /landmarks_w              f64 [L, 3]     optional: world points indexed by landmark_id
//   In h5py: o = f["observations"]; rows of frame i = slice(o["offsets"][i], o["offsets"][i+1]).
//
// Text ("marglab-tracks text 1"): UTF-8 lines, '#' starts a comment line; whitespace-separated.
//   One line per observation:   t_ns track_id u0 v0 u1 v1 [landmark_id is_outlier]
//   u1 v1 = "nan nan" when there is no right match (both or neither); landmark_id and
//   is_outlier (0/1) are optional as a pair (default −1, 0). A line with t_ns alone declares a
//   frame without observations. Lines of one frame are consecutive; t_ns never decreases (equal
//   t_ns = the same frame). Header comments "# sequence: NAME" and "# seed: S" fill the stream's
//   metadata (`run --tracks` requires the sequence, unless --tracks-any-sequence); a header
//   "# marglab-tracks text V" of another version than 1 is refused. landmarks_w is not stored in text. Written numbers are the shortest
//   decimal that reads back to the same double, so a round trip is exact.
//
// Reading validates and throws InputError(file, line, what): text errors name the line; HDF5
// errors use line 0 and name the dataset and row (wrong sizes, offsets, non-increasing t_ns,
// non-finite u0/v0, duplicate track ids in a frame, u1/v1 not NaN exactly when has_right = 0).
// An HDF5 track file is a user's input: readTracksHdf5 reads it in a child process first
// (core/io/hdf5_trust.h), then decodes it (TrackFileContent) and checks what it decoded
// (tracksFromContent — the part fuzzed in CI, fuzz_track_content).

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/data/tracks.h"
#include "core/data/types.h"

namespace marglab {

inline constexpr const char* kTrackFormatName = "marglab-tracks";
inline constexpr int kTrackFormatVersion = 1;

// An HDF5 track file as libhdf5 decoded it, before any check: the attributes ("" and 0 when
// absent) and the datasets of the layout above, absent optional columns filled with their
// defaults. A file of another format or version is decoded no further than its attributes.
struct TrackFileContent {
  std::string format;
  int format_version = 0;
  std::string sequence;
  uint64_t seed = 0;
  std::vector<int64_t> t_ns, offsets, track_id, landmark_id;
  std::vector<double> u0, v0, u1, v1;
  std::vector<uint8_t> has_right, is_outlier;
  std::optional<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> landmarks_w;
};

// The HDF5 track file at path decoded by libhdf5 in this process, without the trust boundary:
// readTracksHdf5 runs it in its child, fuzz_track_hdf5 (the campaign through libhdf5) directly.
TrackFileContent readTrackFileContent(const std::string& path);
// The stream a decoded track file holds, checked as described above (InputError(path, 0, what)).
TrackStream tracksFromContent(const std::string& path, const TrackFileContent& content);

void writeTracksHdf5(const std::string& path, const TrackStream& stream,
                     bool with_landmarks = true);
TrackStream readTracksHdf5(const std::string& path);

void writeTracksText(const std::string& path, const TrackStream& stream);
TrackStream readTracksText(const std::string& path);

// By extension: ".h5" / ".hdf5" → HDF5, else text.
void writeTrackFile(const std::string& path, const TrackStream& stream);
// By content: HDF5 signature → HDF5, else text.
TrackStream readTrackFile(const std::string& path);

// Whether the tracks read from `path` belong to `sequence` (`run --tracks FILE --dataset SEQ`):
// the file has frames; it records its sequence, and that is SEQ (a folder "X_images" and the
// shipped "X" are one recording); every frame lies at one of SEQ's camera timestamps; no pixel
// lies farther than one image size outside SEQ's cam0 image.
// Tracks of another recording would otherwise be paired with this one's ground truth and IMU and
// give a plausible-looking, meaningless estimate. Throws InputError naming the file and what was
// expected.
void checkTracksBelongTo(const TrackStream& stream, const std::string& path,
                         const Sequence& sequence);

}  // namespace marglab
