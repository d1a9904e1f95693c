#include "core/frontend/image_folder.h"

#include <fmt/core.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <system_error>

#include "core/common/error.h"
#include "core/data/parsers.h"
#include "core/data/sequence.h"
#include "core/data/text_file.h"
#include "core/frontend/optical_flow.h"

namespace marglab {

namespace fs = std::filesystem;

namespace {

bool isDir(const fs::path& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}

bool isFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

struct ListedImage {
  std::string path;
  std::string listed_at;  // "data.csv:LINE"
};

// "t_ns,filename" rows of an ASL camera list, file names resolved against <cam>/data/.
std::map<int64_t, ListedImage> readAslImageList(const fs::path& cam) {
  const std::string list = (cam / "data.csv").string();
  TextFile file(list);
  std::map<int64_t, ListedImage> images;
  std::string_view line;
  while (file.nextDataLine(line)) {
    const auto f = splitFields(line, ",");
    if (f.size() != 2) file.fail("expected 'timestamp [ns],filename'");
    const int64_t t = parseInt64(f[0], file, "column 1 (t [ns])");
    images[t] = {(cam / "data" / std::string(f[1])).string(),
                 fmt::format("{}:{}", list, file.lineNumber())};
  }
  return images;
}

const std::string& existing(const ListedImage& image) {
  if (!isFile(image.path)) {
    throw InputError(image.path, 0,
                     fmt::format("image named by {} does not exist", image.listed_at));
  }
  return image.path;
}

std::optional<StereoImageList> aslImages(const fs::path& mav) {
  if (!isDir(mav / "cam0" / "data")) return std::nullopt;
  const auto left = readAslImageList(mav / "cam0");
  const auto right = readAslImageList(mav / "cam1");
  StereoImageList list;
  list.source = (mav / "cam{0,1}" / "data.csv").string();
  // Every left image must exist; right rows without a left frame are not used (the shipped
  // cam1/data.csv lists 4 frames beyond the 95 images, as the excerpt it was copied from does).
  for (const auto& [t, image] : left) {
    const std::string& path = existing(image);
    const auto r = right.find(t);
    if (r == right.end()) {  // right frame dropped: no stereo frame
      ++list.unpaired_left;
      continue;
    }
    list.t_ns.push_back(t);
    list.left.push_back(path);
    list.right.push_back(existing(r->second));
  }
  // Without a single stereo frame every later step would only say "no frame": say which list.
  if (list.t_ns.empty() && !left.empty()) {
    const std::string cam1 = (mav / "cam1" / "data.csv").string();
    if (right.empty()) {
      throw InputError(cam1, 0, "lists no images (expected the right camera's frames)");
    }
    throw InputError(
        cam1, 0,
        fmt::format("none of its {} timestamps is one of the {} of cam0/data.csv "
                    "(expected the stereo frames at the same times; the first: "
                    "cam0 {} ns, cam1 {} ns)",
                    right.size(), left.size(), left.begin()->first, right.begin()->first));
  }
  return list;
}

// A KITTI camera folder (or one of its images) that is there but cannot be read — a symbolic
// link loop, no permission — is said to be so, not reported as an image missing.
void checkReadable(const fs::path& path, bool folder) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!ec && folder && fs::is_directory(status)) fs::directory_iterator(path, ec);
  if (!ec || ec == std::errc::no_such_file_or_directory) return;
  throw InputError(
      path.string(), 0,
      fmt::format("cannot read the {}: {}{}", folder ? "folder" : "image", ec.message(),
                  ec == std::errc::too_many_symbolic_link_levels ? " (a symbolic link loop)" : ""));
}

std::optional<StereoImageList> kittiImages(const Sequence& seq) {
  const fs::path dir = seq.directory;
  checkReadable(dir / "image_0", true);
  if (!isDir(dir / "image_0")) return std::nullopt;
  checkReadable(dir / "image_1", true);
  StereoImageList list;
  list.source = (dir / "image_{0,1}").string();
  for (std::size_t i = 0; i < seq.cam_t_ns.size(); ++i) {
    const std::string name = fmt::format("{:06d}.png", i);
    for (const char* cam : {"image_0", "image_1"}) {
      const fs::path image = dir / cam / name;
      if (!isFile(image)) {
        checkReadable(image, false);
        throw InputError(image.string(), 0,
                         fmt::format("expected one image per line of {} ({} lines)", seq.cam_file,
                                     seq.cam_t_ns.size()));
      }
    }
    list.t_ns.push_back(seq.cam_t_ns[i]);
    list.left.push_back((dir / "image_0" / name).string());
    list.right.push_back((dir / "image_1" / name).string());
  }
  return list;
}

// "V1_01_easy_images" (or "_keyframes") → "euroc/V1_01_easy"; "dataset-room1_512_16" → "tumvi/room1"; "07" →
// "kitti/07": the shipped sequence of the same name, if there is one.
std::string shippedByName(const Sequence& seq) {
  std::string folder = fs::absolute(seq.directory).lexically_normal().filename().string();
  if (folder == "mav0") {
    folder = fs::absolute(seq.directory).lexically_normal().parent_path().filename().string();
  }
  for (const std::string suffix : {"_images", "_keyframes"}) {
    if (folder.size() > suffix.size() &&
        folder.compare(folder.size() - suffix.size(), suffix.size(), suffix) == 0) {
      folder.resize(folder.size() - suffix.size());
    }
  }
  if (folder.rfind("dataset-", 0) == 0) {
    folder = folder.substr(
        8, folder.find("_512") == std::string::npos ? std::string::npos : folder.find("_512") - 8);
  }
  const std::string name = std::string(datasetKindName(seq.kind)) + "/" + folder;
  const std::vector<std::string> shipped = listSequences();
  return std::find(shipped.begin(), shipped.end(), name) != shipped.end() ? name : "";
}

// EuRoC / TUM-VI: the shipped sequence whose camera timestamps contain the folder's first one.
std::string shippedByTimestamp(const Sequence& seq) {
  if (seq.kind == DatasetKind::kKitti || seq.cam_t_ns.empty()) return "";
  const std::string prefix = std::string(datasetKindName(seq.kind)) + "/";
  for (const std::string& name : listSequences()) {
    if (name.rfind(prefix, 0) != 0) continue;
    const std::string file =
        findPlainOrGz((fs::path(datasetsRoot()) / name / "cam0_timestamps_ns.txt").string());
    if (file.empty()) continue;
    const std::vector<int64_t> t = readTimestampList(file);
    if (std::binary_search(t.begin(), t.end(), seq.cam_t_ns.front())) return name;
  }
  return "";
}

void applyFallback(ImageSequence* out) {
  Sequence& seq = out->sequence;
  const bool needs_gt = !seq.hasTrajectory();
  const bool needs_imu = seq.kind != DatasetKind::kKitti && seq.imu_file.empty();
  if (!needs_gt && !needs_imu) return;
  std::string name = shippedByName(seq);
  if (name.empty()) name = shippedByTimestamp(seq);
  if (name.empty() || name == seq.name) return;
  const Sequence shipped = loadSequence(name);
  if (needs_gt && shipped.hasTrajectory()) {
    seq.gt = shipped.gt;
    seq.gt_imu_state = shipped.gt_imu_state;
    seq.gt_is_estimate = shipped.gt_is_estimate;
    seq.gt_source = shipped.gt_source + " of " + name;
    seq.gt_file = shipped.gt_file;
    out->fallback = name;
  }
  if (needs_imu && shipped.imu) {
    seq.imu = shipped.imu;
    seq.imu_file = shipped.imu_file;
    seq.imu_noise = shipped.imu_noise;
    out->fallback = name;
  }
}

}  // namespace

std::optional<StereoImageList> findStereoImages(const Sequence& sequence) {
  if (sequence.kind == DatasetKind::kKitti) return kittiImages(sequence);
  const fs::path dir = sequence.directory;
  if (isDir(dir / "mav0")) return aslImages(dir / "mav0");
  if (isDir(dir / "cam0") && isFile(dir / "cam0" / "data.csv")) return aslImages(dir);
  return std::nullopt;
}

ImageSequence loadImageSequence(const std::string& name_or_path) {
  ImageSequence out;
  out.sequence = loadSequence(name_or_path);
  out.images = findStereoImages(out.sequence);
  if (out.images && out.sequence.kind == DatasetKind::kKitti && !out.images->left.empty()) {
    // calib.txt has no image size (the loader assumes 1241x376); the first image defines it.
    const cv::Mat first = readGreyImage(out.images->left.front(), 0, 0);
    for (CameraCalib* cam : {&out.sequence.calib.cam0, &out.sequence.calib.cam1}) {
      cam->width = first.cols;
      cam->height = first.rows;
    }
  }
  applyFallback(&out);
  return out;
}

std::string unpairedFramesNote(const StereoImageList& list) {
  if (list.unpaired_left == 0) return "";
  return fmt::format(
      "{} of the {} cam0 frames have no cam1 frame at the same timestamp and are "
      "dropped ({})",
      list.unpaired_left, list.unpaired_left + list.size(), list.source);
}

}  // namespace marglab
