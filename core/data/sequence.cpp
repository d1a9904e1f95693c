#include "core/data/sequence.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <tuple>

#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/common/statistics.h"
#include "core/data/parsers.h"
#include "core/data/plausibility.h"
#include "core/data/text_file.h"

namespace marglab {

namespace fs = std::filesystem;

const char* datasetKindName(DatasetKind kind) {
  switch (kind) {
    case DatasetKind::kEuroc:
      return "euroc";
    case DatasetKind::kTumvi:
      return "tumvi";
    case DatasetKind::kKitti:
      return "kitti";
  }
  return "?";
}

DatasetDefaults datasetDefaults(DatasetKind kind) {
  if (kind == DatasetKind::kKitti) return {30.0, 100.0, 1};
  return {50.0, 5.0, 5};
}

namespace {

constexpr const char* kDatasetFolders[] = {"euroc", "tumvi", "kitti"};
constexpr double kNominalImuRateHz = 200.0;
constexpr double kImuRateTolerance = 0.1;
// ATE association skips frames whose neighbouring GT samples are further apart (docs/design.md §4).
constexpr double kGtGapNoteS = 0.11;

bool isDir(const fs::path& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}

std::string joinNames(const std::vector<std::string>& names) {
  std::string text;
  for (const auto& name : names) text += (text.empty() ? "" : ", ") + name;
  return text;
}

// "tumvi/dataset-room1_512_16" → "tumvi/room1" (the TUM-VI export's folder name).
std::string canonicalName(std::string name) {
  while (!name.empty() && name.back() == '/') name.pop_back();
  const std::string prefix = "tumvi/dataset-";
  if (name.rfind(prefix, 0) == 0) {
    name = "tumvi/" + name.substr(prefix.size());
    const std::size_t suffix = name.find("_512");
    if (suffix != std::string::npos) name.resize(suffix);
  }
  return name;
}

void loadTrajectoryFile(Sequence& seq, const std::string& asl_csv, const std::string& tum_txt) {
  const PlausibilityLimits& limits = plausibilityLimits(seq.kind);
  if (const std::string asl = findPlainOrGz(asl_csv); !asl.empty()) {
    AslGroundTruth gt = readAslGroundTruth(asl, &limits);
    seq.gt = std::move(gt.trajectory);
    seq.gt_imu_state = std::move(gt.state);
    seq.gt_source = "ASL csv";
    seq.gt_file = asl;
  } else if (const std::string tum = tum_txt.empty() ? "" : findPlainOrGz(tum_txt); !tum.empty()) {
    seq.gt = readTumTrajectory(tum, &limits);
    seq.gt_source = "TUM txt";
    seq.gt_file = tum;
  }
}

void loadImu(Sequence& seq, const std::string& file, const LoadOptions& options) {
  seq.imu_file = findPlainOrGz(file);
  if (!seq.imu_file.empty() && options.load_imu) {
    seq.imu = readAslImu(seq.imu_file, &plausibilityLimits(seq.kind));
  }
}

void loadCalibration(Sequence& seq, const fs::path& calib_dir) {
  if (seq.kind == DatasetKind::kEuroc) {
    seq.calib.cam0 = readEurocSensorYaml((calib_dir / "cam0_sensor.yaml").string());
    seq.calib.cam1 = readEurocSensorYaml((calib_dir / "cam1_sensor.yaml").string());
    seq.calib_source = (calib_dir / "cam{0,1}_sensor.yaml").string();
  } else {
    const fs::path chain = calib_dir / "openvins_kalibr_imucam_chain.yaml";
    seq.calib = readKalibrCamchain(chain.string());
    seq.calib_source = chain.string();
  }
  seq.imu_noise = readKalibrImuNoise((calib_dir / "openvins_kalibr_imu_chain.yaml").string());
}

DatasetKind shippedKind(const fs::path& dir) {
  const std::string parent = fs::absolute(dir).lexically_normal().parent_path().filename().string();
  if (parent == "euroc") return DatasetKind::kEuroc;
  if (parent == "tumvi") return DatasetKind::kTumvi;
  throw InputError(dir.string(), 0,
                   "expected this folder (shipped layout) inside a folder named euroc or tumvi, "
                   "next to its calib/ folder");
}

// EuRoC has state_groundtruth_estimate0/, TUM-VI mocap0/.
DatasetKind aslKind(const fs::path& mav) {
  const bool has_state_gt =
      !findPlainOrGz((mav / "state_groundtruth_estimate0/data.csv").string()).empty();
  const bool has_mocap = !findPlainOrGz((mav / "mocap0/data.csv").string()).empty();
  return has_mocap && !has_state_gt ? DatasetKind::kTumvi : DatasetKind::kEuroc;
}

// Shipped layout: <root>/<kind>/<seq>/{cam0_timestamps_ns.txt, gt_*.{csv,txt}, imu0_asl.csv}(.gz).
void loadShippedLayout(Sequence& seq, const fs::path& dir, const LoadOptions& options) {
  seq.kind = shippedKind(dir);
  seq.cam_file = findPlainOrGz((dir / "cam0_timestamps_ns.txt").string());
  seq.cam_t_ns = readTimestampList(seq.cam_file);
  loadTrajectoryFile(seq, (dir / "gt_asl.csv").string(), (dir / "gt_tum.txt").string());
  if (seq.gt.empty()) {
    for (const auto& entry : fs::directory_iterator(dir)) {
      const std::string file = entry.path().filename().string();
      if (file.rfind("estimate_", 0) != 0) continue;
      // estimate_<method>_tum.txt[.gz]: a VIO output used as a smooth trajectory, not GT.
      std::string method = file.substr(9, file.find('_', 9) - 9);
      if (method == "okvis") method = "OKVIS";
      if (method == "vinsmono") method = "VINS-Mono";
      seq.gt = readTumTrajectory(entry.path().string(), &plausibilityLimits(seq.kind));
      seq.gt_is_estimate = true;
      seq.gt_source = method + " estimate";
      seq.gt_file = entry.path().string();
      break;
    }
  }
  loadImu(seq, (dir / "imu0_asl.csv").string(), options);
  loadCalibration(seq, dir.parent_path() / "calib");
}

std::vector<fs::path> camchainCandidates(const fs::path& dir, const fs::path& mav) {
  std::vector<fs::path> found;
  for (const fs::path& d : {dir, dir / "dso", mav}) {
    if (!isDir(d)) continue;
    for (const auto& entry : fs::directory_iterator(d)) {
      const std::string file = entry.path().filename().string();
      const bool yaml = file.size() > 5 && file.substr(file.size() - 5) == ".yaml";
      if (yaml && (file.find("camchain") != std::string::npos ||
                   file.find("imucam") != std::string::npos)) {
        found.push_back(entry.path());
      }
    }
  }
  std::sort(found.begin(), found.end());
  return found;
}

// Original ASL layout of EuRoC / TUM-VI: <dir>/mav0/... or <dir> = mav0.
void loadAslLayout(Sequence& seq, const fs::path& dir, const fs::path& mav,
                   const LoadOptions& options) {
  seq.kind = aslKind(mav);
  seq.cam_file = findPlainOrGz((mav / "cam0/data.csv").string());
  if (seq.cam_file.empty()) {
    throw InputError((mav / "cam0/data.csv").string(), 0, "expected an existing file (not found)");
  }
  seq.cam_t_ns = readTimestampList(seq.cam_file);
  loadTrajectoryFile(
      seq,
      (mav / (seq.kind == DatasetKind::kEuroc ? "state_groundtruth_estimate0" : "mocap0") /
       "data.csv")
          .string(),
      "");
  loadImu(seq, (mav / "imu0/data.csv").string(), options);

  const fs::path shipped_calib = fs::path(datasetsRoot()) / datasetKindName(seq.kind) / "calib";
  if (seq.kind == DatasetKind::kEuroc) {
    seq.calib.cam0 = readEurocSensorYaml((mav / "cam0/sensor.yaml").string());
    seq.calib.cam1 = readEurocSensorYaml((mav / "cam1/sensor.yaml").string());
    seq.calib_source = (mav / "cam{0,1}/sensor.yaml").string();
    const std::string imu_yaml = (mav / "imu0/sensor.yaml").string();
    seq.imu_noise = findPlainOrGz(imu_yaml).empty() ? ImuNoise{} : readKalibrImuNoise(imu_yaml);
  } else {
    const std::vector<fs::path> chains = camchainCandidates(dir, mav);
    const fs::path chain =
        chains.empty() ? shipped_calib / "openvins_kalibr_imucam_chain.yaml" : chains.front();
    seq.calib = readKalibrCamchain(chain.string());
    seq.calib_source = chain.string();
    const std::string imu_yaml = (mav / "imu0/sensor.yaml").string();
    seq.imu_noise =
        readKalibrImuNoise(findPlainOrGz(imu_yaml).empty()
                               ? (shipped_calib / "openvins_kalibr_imu_chain.yaml").string()
                               : imu_yaml);
  }
}

void loadKittiLayout(Sequence& seq, const fs::path& dir) {
  seq.kind = DatasetKind::kKitti;
  seq.cam_file = findPlainOrGz((dir / "times.txt").string());
  seq.cam_t_ns = readKittiTimes(seq.cam_file);
  const std::string calib = findPlainOrGz((dir / "calib.txt").string());
  seq.calib = readKittiCalib(calib);
  seq.calib_source = calib;
  std::string poses = findPlainOrGz((dir / "poses.txt").string());
  if (poses.empty()) {
    // Official layout: dataset/sequences/NN/{times,calib}.txt and dataset/poses/NN.txt.
    const fs::path abs = fs::absolute(dir).lexically_normal();
    poses = findPlainOrGz(
        (abs.parent_path().parent_path() / "poses" / (abs.filename().string() + ".txt")).string());
  }
  if (!poses.empty()) {
    seq.gt = readKittiPoses(poses, seq.cam_t_ns, &plausibilityLimits(seq.kind));
    seq.gt_source = "KITTI poses.txt";
    seq.gt_file = poses;
  }
}

enum class Layout { kKitti, kKittiRoot, kShipped, kAsl, kAslMav };

// The folder's layout; throws InputError when it cannot be read or has none of them.
Layout detectLayout(const fs::path& dir) {
  std::error_code ec;
  fs::directory_iterator listing(dir, ec);
  if (ec) throw InputError(dir.string(), 0, "cannot read the folder: " + ec.message());
  const auto has = [&](const char* file) { return !findPlainOrGz((dir / file).string()).empty(); };
  if (has("times.txt") && has("calib.txt")) return Layout::kKitti;
  if (has("cam0_timestamps_ns.txt")) return Layout::kShipped;
  if (isDir(dir / "mav0")) return Layout::kAslMav;
  if (isDir(dir / "cam0") && has("cam0/data.csv")) return Layout::kAsl;
  if (isDir(dir / "sequences")) return Layout::kKittiRoot;
  throw InputError(dir.string(), 0,
                   "expected a sequence folder: EuRoC/TUM-VI with mav0/, KITTI with times.txt + "
                   "calib.txt (or a KITTI download with sequences/), or the shipped layout with "
                   "cam0_timestamps_ns.txt");
}

// A KITTI download <root>/sequences/NN with a single sequence: that sequence's folder.
fs::path kittiSequenceInRoot(const fs::path& root) {
  std::vector<fs::path> found;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(root / "sequences", ec)) {
    if (!findPlainOrGz((entry.path() / "times.txt").string()).empty())
      found.push_back(entry.path());
  }
  if (found.size() != 1) {
    std::vector<std::string> names;
    for (const fs::path& p : found) names.push_back(p.filename().string());
    std::sort(names.begin(), names.end());
    throw InputError((root / "sequences").string(), 0,
                     fmt::format("expected exactly one sequence folder with times.txt, found {} "
                                 "({}): pass the sequence folder sequences/NN",
                                 found.size(), joinNames(names)));
  }
  return found.front();
}

Sequence loadFolder(const fs::path& folder, const std::string& name, const LoadOptions& options) {
  const fs::path dir =
      detectLayout(folder) == Layout::kKittiRoot ? kittiSequenceInRoot(folder) : folder;
  Sequence seq;
  seq.name = name;
  seq.directory = dir.string();
  switch (detectLayout(dir)) {
    case Layout::kKitti:
    case Layout::kKittiRoot:
      loadKittiLayout(seq, dir);
      break;
    case Layout::kShipped:
      loadShippedLayout(seq, dir, options);
      break;
    case Layout::kAslMav:
      loadAslLayout(seq, dir, dir / "mav0", options);
      break;
    case Layout::kAsl:
      loadAslLayout(seq, dir, dir, options);
      break;
  }
  checkSequencePlausibility(seq);
  seq.defaults = datasetDefaults(seq.kind);
  if (seq.name.empty() || seq.name.find('/') == std::string::npos) {
    seq.name = std::string(datasetKindName(seq.kind)) + "/" +
               fs::absolute(dir).lexically_normal().filename().string();
  }
  return seq;
}

struct SequenceFolder {
  fs::path dir;
  std::string name;  // the shipped name, "" for a user's folder
};

// The folder a sequence name or path stands for; throws InputError for neither.
SequenceFolder sequenceFolder(const std::string& name_or_path) {
  const std::string name = canonicalName(name_or_path);
  const fs::path root = datasetsRoot();
  const bool looks_like_path =
      !name_or_path.empty() && (name_or_path.front() == '/' || name_or_path.front() == '.');
  if (!looks_like_path && !name.empty() && isDir(root / name)) return {root / name, name};
  const std::string path = normalizeDatasetArgument(name_or_path);
  if (isDir(path)) return {path, ""};
  throw InputError(
      name_or_path, 0,
      fmt::format("expected a sequence name or an existing folder; sequences in {}: {}",
                  root.string(), joinNames(listSequences())));
}

}  // namespace

std::string normalizeDatasetArgument(const std::string& name_or_path) {
  const bool looks_like_path =
      !name_or_path.empty() && (name_or_path.front() == '/' || name_or_path.front() == '.');
  const std::string name = canonicalName(name_or_path);
  if (!looks_like_path && !name.empty() && isDir(fs::path(datasetsRoot()) / name)) return name;
  if (name_or_path.empty()) return name_or_path;
  std::string path = fs::path(name_or_path).lexically_normal().string();
  while (path.size() > 1 && path.back() == '/') path.pop_back();
  return path;
}

std::string datasetsRoot() {
  const char* env = std::getenv("MARGLAB_DATASETS");
  if (env != nullptr && env[0] != '\0') return env;
  return std::string(sourceDir()) + "/datasets";
}

std::vector<std::string> listSequences() {
  const fs::path root = datasetsRoot();
  std::vector<std::string> names;
  for (const char* dataset : kDatasetFolders) {
    if (!isDir(root / dataset)) continue;
    std::vector<std::string> here;
    for (const auto& entry : fs::directory_iterator(root / dataset)) {
      const std::string folder = entry.path().filename().string();
      if (entry.is_directory() && folder != "calib")
        here.push_back(std::string(dataset) + "/" + folder);
    }
    std::sort(here.begin(), here.end());
    names.insert(names.end(), here.begin(), here.end());
  }
  return names;
}

Sequence loadSequence(const std::string& name_or_path, const LoadOptions& options) {
  const SequenceFolder folder = sequenceFolder(name_or_path);
  return loadFolder(folder.dir, folder.name, options);
}

DatasetKind sequenceKind(const std::string& name_or_path) {
  const fs::path dir = sequenceFolder(name_or_path).dir;
  switch (detectLayout(dir)) {
    case Layout::kKitti:
    case Layout::kKittiRoot:
      return DatasetKind::kKitti;
    case Layout::kShipped:
      return shippedKind(dir);
    case Layout::kAslMav:
      return aslKind(dir / "mav0");
    case Layout::kAsl:
      break;
  }
  return aslKind(dir);
}

std::pair<std::size_t, std::size_t> framesWithinTrajectory(const Sequence& sequence) {
  if (sequence.gt.empty()) return {0, 0};
  const auto& cam = sequence.cam_t_ns;
  const auto first = std::lower_bound(cam.begin(), cam.end(), sequence.gt.t_ns.front());
  const auto last = std::upper_bound(first, cam.end(), sequence.gt.t_ns.back());
  return {static_cast<std::size_t>(first - cam.begin()),
          static_cast<std::size_t>(last - cam.begin())};
}

double checkImuCoverage(const Sequence& seq) {
  if (!seq.imu) return 0;
  const auto& cam = seq.cam_t_ns;
  if (cam.empty()) throw InputError(seq.cam_file, 0, "expected at least 2 camera timestamps");
  const auto& t = seq.imu->t_ns;
  if (t.size() < 2) throw InputError(seq.imu_file, 0, "expected at least 2 IMU samples");
  const double rate_hz = 1e9 / static_cast<double>(medianGapNs(t));
  if (std::abs(rate_hz / kNominalImuRateHz - 1.0) > kImuRateTolerance) {
    throw InputError(seq.imu_file, 0,
                     fmt::format("expected an IMU rate of {:.0f} Hz ± {:.0f} %, found {:.1f} Hz",
                                 kNominalImuRateHz, 100 * kImuRateTolerance, rate_hz));
  }
  std::size_t first = 0, last = cam.size();
  if (seq.hasTrajectory()) std::tie(first, last) = framesWithinTrajectory(seq);
  if (first >= last) return rate_hz;  // no frame to cover (checkSequence says so)
  if (t.front() > cam[first] || t.back() < cam[last - 1]) {
    throw InputError(seq.imu_file, 0,
                     fmt::format("expected the IMU [{}, {}] ns to cover the camera frames "
                                 "[{}, {}] ns{}",
                                 t.front(), t.back(), cam[first], cam[last - 1],
                                 seq.hasTrajectory() ? " within the trajectory" : ""));
  }
  return rate_hz;
}

SequenceCheck checkSequence(const Sequence& seq) {
  SequenceCheck check;
  const auto& cam = seq.cam_t_ns;
  check.frames = cam.size();
  if (cam.size() < 2) throw InputError(seq.cam_file, 0, "expected at least 2 camera timestamps");
  check.duration_s = 1e-9 * static_cast<double>(cam.back() - cam.front());

  if (!seq.hasTrajectory()) {
    check.timestamps_only = true;
    check.notes.push_back("timestamps only (no trajectory)");
  } else {
    const auto [first, last] = framesWithinTrajectory(seq);
    check.frames_in_gt = last - first;
    if (check.frames_in_gt == 0) {
      throw InputError(
          seq.gt_file, 0,
          fmt::format("expected the trajectory [{}, {}] ns to overlap the camera timestamps "
                      "[{}, {}] ns of {}",
                      seq.gt.t_ns.front(), seq.gt.t_ns.back(), cam.front(), cam.back(),
                      seq.cam_file));
    }
    for (std::size_t i = 1; i < seq.gt.size(); ++i) {
      check.max_gt_gap_s = std::max(
          check.max_gt_gap_s, 1e-9 * static_cast<double>(seq.gt.t_ns[i] - seq.gt.t_ns[i - 1]));
    }
    if (seq.gt_is_estimate) check.notes.push_back(seq.gt_source + ", not ground truth");
    if (const std::string note = pathLengthNote(seq); !note.empty()) check.notes.push_back(note);
    if (check.frames_in_gt < check.frames) {
      check.notes.push_back(
          fmt::format("trajectory spans {} of {} frames", check.frames_in_gt, check.frames));
    }
    const double median_dt_s =
        seq.gt.size() > 1 ? 1e-9 * static_cast<double>(medianGapNs(seq.gt.t_ns)) : 0.0;
    if (check.max_gt_gap_s > std::max(kGtGapNoteS, 2 * median_dt_s)) {
      check.notes.push_back(fmt::format("trajectory gaps up to {:.2f} s", check.max_gt_gap_s));
    }
  }

  if (seq.imu) check.imu_rate_hz = checkImuCoverage(seq);
  return check;
}

}  // namespace marglab
