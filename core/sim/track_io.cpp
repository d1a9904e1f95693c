#include "core/sim/track_io.h"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <unordered_set>
#include <vector>

#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/io/hdf5.h"
#include "core/io/hdf5_trust.h"
#include "core/io/text_input.h"

namespace marglab {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Checks the per-frame invariants shared by both readers; where() names the offending place.
template <typename Where>
void validateFrame(const std::string& path, const TrackFrame& frame, const Where& where) {
  std::unordered_set<int64_t> ids;
  for (std::size_t k = 0; k < frame.observations.size(); ++k) {
    const StereoObservation& o = frame.observations[k];
    if (o.track_id < 0) throw InputError(path, where(k).first, where(k).second + "track_id < 0");
    if (!ids.insert(o.track_id).second) {
      throw InputError(path, where(k).first,
                       where(k).second + fmt::format("track_id {} occurs twice in frame t_ns {}",
                                                     o.track_id, frame.t_ns));
    }
  }
}

}  // namespace

// ---- HDF5 ---------------------------------------------------------------------------------------

void writeTracksHdf5(const std::string& path, const TrackStream& stream, bool with_landmarks) {
  std::vector<int64_t> t_ns, offsets{0}, track_id, landmark_id;
  std::vector<double> u0, v0, u1, v1;
  std::vector<uint8_t> has_right, is_outlier;
  for (const TrackFrame& frame : stream.frames) {
    t_ns.push_back(frame.t_ns);
    for (const StereoObservation& o : frame.observations) {
      track_id.push_back(o.track_id);
      u0.push_back(o.uv0.x());
      v0.push_back(o.uv0.y());
      has_right.push_back(o.has_right ? 1 : 0);
      u1.push_back(o.has_right ? o.uv1.x() : kNaN);
      v1.push_back(o.has_right ? o.uv1.y() : kNaN);
      landmark_id.push_back(o.landmark_id);
      is_outlier.push_back(o.is_outlier ? 1 : 0);
    }
    offsets.push_back(static_cast<int64_t>(track_id.size()));
  }

  h5::File file = h5::File::create(path);
  file.setAttr("format", std::string(kTrackFormatName));
  file.setAttr("format_version", kTrackFormatVersion);
  file.setAttr("sequence", stream.sequence);
  file.setAttr("seed", static_cast<int64_t>(stream.seed));
  // Chunked + shuffle/deflate: the columns compress well (monotonic ids, smooth pixels).
  constexpr hsize_t kChunk = 1 << 16;
  constexpr int kDeflate = 4;
  h5::appendable<int64_t>(file, "frames/t_ns", kChunk, kDeflate).append(t_ns);
  const h5::Group obs = file.group("observations");
  h5::appendable<int64_t>(obs, "offsets", kChunk, kDeflate).append(offsets);
  h5::appendable<int64_t>(obs, "track_id", kChunk, kDeflate).append(track_id);
  h5::appendable<double>(obs, "u0", kChunk, kDeflate).append(u0);
  h5::appendable<double>(obs, "v0", kChunk, kDeflate).append(v0);
  h5::appendable<uint8_t>(obs, "has_right", kChunk, kDeflate).append(has_right);
  h5::appendable<double>(obs, "u1", kChunk, kDeflate).append(u1);
  h5::appendable<double>(obs, "v1", kChunk, kDeflate).append(v1);
  h5::appendable<int64_t>(obs, "landmark_id", kChunk, kDeflate).append(landmark_id);
  h5::appendable<uint8_t>(obs, "is_outlier", kChunk, kDeflate).append(is_outlier);
  if (with_landmarks && !stream.landmarks_w.empty()) {
    std::vector<double> xyz;
    xyz.reserve(3 * stream.landmarks_w.size());
    for (const Eigen::Vector3d& p : stream.landmarks_w)
      xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
    h5::appendableRows<double>(file, "landmarks_w", 3, kChunk, kDeflate).append(xyz);
  }
  file.commit();
}

// Decodes as far as tracksFromContent looks: a file of another format or version is refused on its
// attributes alone, whatever else it holds.
TrackFileContent readTrackFileContent(const std::string& path) {
  const h5::File file = h5::File::openReadOnly(path);
  TrackFileContent c;
  if (file.hasAttr("format")) c.format = file.attr<std::string>("format");
  if (c.format != kTrackFormatName) return c;
  c.format_version = file.attr<int>("format_version");
  if (c.format_version != kTrackFormatVersion) return c;
  if (file.hasAttr("sequence")) c.sequence = file.attr<std::string>("sequence");
  if (file.hasAttr("seed")) c.seed = static_cast<uint64_t>(file.attr<int64_t>("seed"));
  c.t_ns = file.readVector<int64_t>("frames/t_ns");
  const h5::Group obs = file.openGroup("observations");
  c.offsets = obs.readVector<int64_t>("offsets");
  c.track_id = obs.readVector<int64_t>("track_id");
  c.u0 = obs.readVector<double>("u0");
  c.v0 = obs.readVector<double>("v0");
  c.has_right = obs.readVector<uint8_t>("has_right");
  c.u1 = obs.readVector<double>("u1");
  c.v1 = obs.readVector<double>("v1");
  const std::size_t K = c.track_id.size();
  c.landmark_id = obs.exists("landmark_id") ? obs.readVector<int64_t>("landmark_id")
                                            : std::vector<int64_t>(K, -1);
  c.is_outlier =
      obs.exists("is_outlier") ? obs.readVector<uint8_t>("is_outlier") : std::vector<uint8_t>(K, 0);
  if (file.exists("landmarks_w")) c.landmarks_w = file.readMatrix<double>("landmarks_w");
  return c;
}

namespace {

using Fail = std::function<void(const std::string&)>;

// The format and version, and the lengths of the columns against each other.
void checkLayout(const TrackFileContent& c, const Fail& fail) {
  if (c.format != kTrackFormatName) {
    fail(fmt::format("not a track file: attribute format = \"{}\" expected", kTrackFormatName));
  }
  if (c.format_version != kTrackFormatVersion) {
    fail(fmt::format("format_version {} not supported (expected {})", c.format_version,
                     kTrackFormatVersion));
  }
  if (c.offsets.size() != c.t_ns.size() + 1) {
    fail(fmt::format("/observations/offsets has {} entries, expected {} (frames + 1)",
                     c.offsets.size(), c.t_ns.size() + 1));
  }
  const std::size_t K = c.track_id.size();
  const std::pair<const char*, std::size_t> columns[] = {{"u0", c.u0.size()},
                                                         {"v0", c.v0.size()},
                                                         {"has_right", c.has_right.size()},
                                                         {"u1", c.u1.size()},
                                                         {"v1", c.v1.size()},
                                                         {"landmark_id", c.landmark_id.size()},
                                                         {"is_outlier", c.is_outlier.size()}};
  for (const auto& [name, size] : columns) {
    if (size != K) {
      fail(fmt::format("/observations/{} has {} rows, track_id has {}", name, size, K));
    }
  }
  if (c.offsets.front() != 0 || c.offsets.back() != static_cast<int64_t>(K)) {
    fail(fmt::format("/observations/offsets must start at 0 and end at {}", K));
  }
  if (c.landmarks_w && c.landmarks_w->cols() != 3) fail("/landmarks_w: expected 3 columns");
}

// Observation row k, checked: finite left pixel, right pixel finite exactly when has_right, a
// landmark id within /landmarks_w (n_landmarks; 0: the file has none).
StereoObservation observationAt(const TrackFileContent& c, std::size_t k, std::size_t n_landmarks,
                                const Fail& fail) {
  if (!std::isfinite(c.u0[k]) || !std::isfinite(c.v0[k])) {
    fail(fmt::format("/observations row {}: u0, v0 must be finite", k));
  }
  if (c.has_right[k] > 1) fail(fmt::format("/observations/has_right[{}] is not 0/1", k));
  const bool right_finite = std::isfinite(c.u1[k]) && std::isfinite(c.v1[k]);
  const bool right_nan = std::isnan(c.u1[k]) && std::isnan(c.v1[k]);
  if (c.has_right[k] ? !right_finite : !right_nan) {
    fail(
        fmt::format("/observations row {}: u1, v1 must be finite when has_right = 1 and NaN "
                    "when 0",
                    k));
  }
  StereoObservation o;
  o.track_id = c.track_id[k];
  o.uv0 = Eigen::Vector2d(c.u0[k], c.v0[k]);
  o.has_right = c.has_right[k] != 0;
  if (o.has_right) o.uv1 = Eigen::Vector2d(c.u1[k], c.v1[k]);
  o.landmark_id = c.landmark_id[k];
  o.is_outlier = c.is_outlier[k] != 0;
  if (n_landmarks > 0 && o.landmark_id >= static_cast<int64_t>(n_landmarks)) {
    fail(fmt::format("/observations/landmark_id[{}] = {} beyond /landmarks_w", k, o.landmark_id));
  }
  return o;
}

}  // namespace

TrackStream tracksFromContent(const std::string& path, const TrackFileContent& c) {
  const Fail fail = [&](const std::string& what) { throw InputError(path, 0, what); };
  checkLayout(c, fail);
  TrackStream stream;
  stream.sequence = c.sequence;
  stream.seed = c.seed;
  if (c.landmarks_w) {
    for (Eigen::Index i = 0; i < c.landmarks_w->rows(); ++i) {
      stream.landmarks_w.push_back(c.landmarks_w->row(i));
    }
  }
  const std::vector<int64_t>& t_ns = c.t_ns;
  const std::vector<int64_t>& offsets = c.offsets;
  const std::size_t K = c.track_id.size();
  stream.frames.resize(t_ns.size());
  for (std::size_t i = 0; i < t_ns.size(); ++i) {
    if (i > 0 && t_ns[i] <= t_ns[i - 1]) {
      fail(fmt::format("/frames/t_ns[{}] = {} is not after t_ns[{}] = {}", i, t_ns[i], i - 1,
                       t_ns[i - 1]));
    }
    if (offsets[i + 1] < offsets[i] || offsets[i + 1] > static_cast<int64_t>(K)) {
      fail(fmt::format("/observations/offsets[{}] = {} decreases or exceeds {}", i + 1,
                       offsets[i + 1], K));
    }
    TrackFrame& frame = stream.frames[i];
    frame.t_ns = t_ns[i];
    for (auto k = static_cast<std::size_t>(offsets[i]);
         k < static_cast<std::size_t>(offsets[i + 1]); ++k) {
      frame.observations.push_back(observationAt(c, k, stream.landmarks_w.size(), fail));
    }
    validateFrame(path, frame, [&](std::size_t k) {
      return std::make_pair(0, fmt::format("/observations row {}: ", offsets[i] + k));
    });
  }
  return stream;
}

// Read whole in a child first (the trust boundary: a track file is a user's input), then here.
TrackStream readTracksHdf5(const std::string& path) {
  const auto read = [&path] { return tracksFromContent(path, readTrackFileContent(path)); };
  h5::checkReadableInChild(path, [&read] { read(); });
  return read();
}

// ---- Text ---------------------------------------------------------------------------------------

void writeTracksText(const std::string& path, const TrackStream& stream) {
  AtomicFile out(path);
  fmt::memory_buffer buffer;
  fmt::format_to(std::back_inserter(buffer),
                 "# {} text {}\n# sequence: {}\n# seed: {}\n"
                 "# columns: t_ns track_id u0 v0 u1 v1 landmark_id is_outlier\n"
                 "# pixels in the undistorted pinhole image; u1 v1 = nan nan: no right match\n",
                 kTrackFormatName, kTrackFormatVersion, stream.sequence, stream.seed);
  for (const TrackFrame& frame : stream.frames) {
    if (frame.observations.empty()) fmt::format_to(std::back_inserter(buffer), "{}\n", frame.t_ns);
    for (const StereoObservation& o : frame.observations) {
      const double u1 = o.has_right ? o.uv1.x() : kNaN;
      const double v1 = o.has_right ? o.uv1.y() : kNaN;
      fmt::format_to(std::back_inserter(buffer), "{} {} {} {} {} {} {} {}\n", frame.t_ns,
                     o.track_id, o.uv0.x(), o.uv0.y(), u1, v1, o.landmark_id, o.is_outlier ? 1 : 0);
    }
    if (buffer.size() > (1 << 20)) {
      out.write(buffer.data(), buffer.size());
      buffer.clear();
    }
  }
  out.write(buffer.data(), buffer.size());
  out.commit();
}

namespace {

int64_t parseInt(const std::string& token, const std::string& path, int line, const char* what) {
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(token.c_str(), &end, 10);
  if (end == token.c_str() || *end != '\0' || errno == ERANGE) {
    throw InputError(path, line,
                     fmt::format("{}: expected an integer, got \"{}\"", what, shortToken(token)));
  }
  return v;
}

double parseDouble(const std::string& token, const std::string& path, int line, const char* what) {
  char* end = nullptr;
  const double v = std::strtod(token.c_str(), &end);
  if (end == token.c_str() || *end != '\0') {
    throw InputError(path, line,
                     fmt::format("{}: expected a number, got \"{}\"", what, shortToken(token)));
  }
  return v;
}

}  // namespace

namespace {

// The header "# marglab-tracks text 1": another version is refused, not read by guess.
void checkTextVersion(std::istream& rest, const std::string& kind, const std::string& path,
                      int line) {
  std::string version;
  rest >> version;
  if (kind != "text" || version != std::to_string(kTrackFormatVersion)) {
    throw InputError(
        path, line,
        fmt::format("format '{} {} {}' not supported: expected '{} text {}'", kTrackFormatName,
                    shortToken(kind), shortToken(version), kTrackFormatName, kTrackFormatVersion));
  }
}

}  // namespace

TrackStream readTracksText(const std::string& path) {
  std::istringstream in(readTextInput(path, "the track file", kTrackTextLimits));
  TrackStream stream;
  std::vector<std::vector<int>> obs_lines;
  std::string line;
  std::vector<std::string> tokens;
  for (int n = 1; std::getline(in, line); ++n) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::size_t start = line.find_first_not_of(" \t");
    if (start == std::string::npos) continue;
    if (line[start] == '#') {
      const std::string comment = line.substr(start + 1);
      std::istringstream cs(comment);
      std::string key, value;
      cs >> key >> value;
      if (key == "sequence:") stream.sequence = value;
      if (key == kTrackFormatName) checkTextVersion(cs, value, path, n);
      if (key == "seed:")
        stream.seed = static_cast<uint64_t>(std::strtoull(value.c_str(), nullptr, 10));
      continue;
    }
    tokens.clear();
    std::istringstream ls(line);
    for (std::string token; ls >> token;) tokens.push_back(token);
    if (tokens.size() != 1 && tokens.size() != 6 && tokens.size() != 8) {
      throw InputError(path, n,
                       fmt::format("expected 6 or 8 columns (t_ns track_id u0 v0 u1 v1 "
                                   "[landmark_id is_outlier]) or t_ns alone, got {}",
                                   tokens.size()));
    }
    const int64_t t_ns = parseInt(tokens[0], path, n, "t_ns");
    if (stream.frames.empty() || t_ns != stream.frames.back().t_ns) {
      if (!stream.frames.empty() && t_ns < stream.frames.back().t_ns) {
        throw InputError(path, n,
                         fmt::format("t_ns {} is before the previous frame's {} (time must not "
                                     "decrease)",
                                     t_ns, stream.frames.back().t_ns));
      }
      stream.frames.push_back({t_ns, {}});
      obs_lines.emplace_back();
    }
    if (tokens.size() == 1) continue;
    StereoObservation o;
    o.track_id = parseInt(tokens[1], path, n, "track_id");
    o.uv0 = Eigen::Vector2d(parseDouble(tokens[2], path, n, "u0"),
                            parseDouble(tokens[3], path, n, "v0"));
    if (!std::isfinite(o.uv0.x()) || !std::isfinite(o.uv0.y())) {
      throw InputError(path, n, "u0, v0 must be finite");
    }
    const double u1 = parseDouble(tokens[4], path, n, "u1");
    const double v1 = parseDouble(tokens[5], path, n, "v1");
    if (std::isfinite(u1) && std::isfinite(v1)) {
      o.has_right = true;
      o.uv1 = Eigen::Vector2d(u1, v1);
    } else if (!(std::isnan(u1) && std::isnan(v1))) {
      throw InputError(path, n, "u1, v1 must both be numbers or both nan (no right match)");
    }
    if (tokens.size() == 8) {
      o.landmark_id = parseInt(tokens[6], path, n, "landmark_id");
      const int64_t outlier = parseInt(tokens[7], path, n, "is_outlier");
      if (outlier != 0 && outlier != 1) throw InputError(path, n, "is_outlier must be 0 or 1");
      o.is_outlier = outlier == 1;
    }
    stream.frames.back().observations.push_back(o);
    obs_lines.back().push_back(n);
  }
  for (std::size_t i = 0; i < stream.frames.size(); ++i) {
    validateFrame(path, stream.frames[i],
                  [&](std::size_t k) { return std::make_pair(obs_lines[i][k], std::string()); });
  }
  return stream;
}

// ---- Dispatch -----------------------------------------------------------------------------------

void writeTrackFile(const std::string& path, const TrackStream& stream) {
  if (endsWith(path, ".h5") || endsWith(path, ".hdf5")) {
    writeTracksHdf5(path, stream);
  } else {
    writeTracksText(path, stream);
  }
}

TrackStream readTrackFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot open");
  char signature[8] = {};
  in.read(signature, sizeof(signature));
  constexpr char kHdf5Signature[8] = {'\x89', 'H', 'D', 'F', '\r', '\n', '\x1a', '\n'};
  if (in.gcount() == 8 && std::equal(signature, signature + 8, kHdf5Signature)) {
    return readTracksHdf5(path);
  }
  return readTracksText(path);
}

namespace {

std::string recordingOf(std::string name) {
  const std::string suffix = "_images";
  if (name.size() > suffix.size() &&
      name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
    name.resize(name.size() - suffix.size());
  }
  return name;
}

}  // namespace

namespace {

// Pixels of the undistorted image may lie beyond the raw image (a fisheye's corners), but not by
// more than the image's own size: u0 = 1e300 is not a measurement.
void checkPixelsNearTheImage(const TrackStream& stream, const std::string& path,
                             const CameraCalib& cam) {
  if (cam.width <= 0 || cam.height <= 0) return;
  const auto off = [&](const Eigen::Vector2d& uv) {
    return uv.x() < -cam.width || uv.x() > 2.0 * cam.width || uv.y() < -cam.height ||
           uv.y() > 2.0 * cam.height;
  };
  for (const TrackFrame& frame : stream.frames) {
    for (const StereoObservation& o : frame.observations) {
      if (off(o.uv0) || (o.has_right && off(o.uv1))) {
        throw InputError(path, 0,
                         fmt::format("frame t_ns {}, track {}: pixel ({}, {}) lies far outside "
                                     "the {}x{} image (expected within one image size of it)",
                                     frame.t_ns, o.track_id, off(o.uv0) ? o.uv0.x() : o.uv1.x(),
                                     off(o.uv0) ? o.uv0.y() : o.uv1.y(), cam.width, cam.height));
      }
    }
  }
}

}  // namespace

void checkTracksBelongTo(const TrackStream& stream, const std::string& path,
                         const Sequence& sequence) {
  const std::string how =
      "; write the tracks of this sequence with `marglab datasets track` or `datasets simulate`, "
      "or pass --tracks-any-sequence to run on them anyway";
  if (stream.frames.empty()) {
    throw InputError(path, 0,
                     fmt::format("the track file holds no frames (expected the tracks of {}){}",
                                 sequence.name, how));
  }
  if (stream.sequence.empty()) {
    throw InputError(path, 0,
                     fmt::format("the track file does not say its sequence (a '# sequence: NAME' "
                                 "line, or the HDF5 attribute sequence), so it cannot be checked "
                                 "against {}{}",
                                 sequence.name, how));
  }
  if (recordingOf(stream.sequence) != recordingOf(sequence.name)) {
    throw InputError(path, 0,
                     fmt::format("the tracks are of sequence '{}' (recorded in the file), not of "
                                 "{} (--dataset){}",
                                 shortToken(stream.sequence), sequence.name, how));
  }
  const auto& cam = sequence.cam_t_ns;
  std::size_t foreign = 0, first_foreign = 0;
  for (std::size_t i = 0; i < stream.frames.size(); ++i) {
    if (!std::binary_search(cam.begin(), cam.end(), stream.frames[i].t_ns)) {
      if (foreign++ == 0) first_foreign = i;
    }
  }
  if (foreign > 0) {
    throw InputError(
        path, 0,
        fmt::format("{} of its {} frames lie at no camera timestamp of {} (the first: frame {}, "
                    "t_ns {}; the camera timestamps: {}){}",
                    foreign, stream.frames.size(), sequence.name, first_foreign,
                    stream.frames[first_foreign].t_ns, sequence.cam_file, how));
  }
  checkPixelsNearTheImage(stream, path, sequence.calib.cam0);
}

}  // namespace marglab
