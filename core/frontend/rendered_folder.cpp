#include "core/frontend/rendered_folder.h"

#include <fmt/core.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>

#include "core/common/error.h"
#include "core/common/interrupt.h"
#include "core/common/statistics.h"
#include "core/data/sequence.h"
#include "core/frontend/image_file.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/imu_synth.h"
#include "marglab/version.h"

namespace marglab {

namespace fs = std::filesystem;

namespace {

constexpr int64_t kGtMarginNs = 1'000'000'000;  // ground truth beyond the first and last frame

// The shipped sequence `dataset` names, with its IMU; InputError when it is none or has no
// trajectory to render along.
Sequence shippedSequenceWithTrajectory(const std::string& dataset) {
  const std::vector<std::string> names = listSequences();
  if (std::find(names.begin(), names.end(), dataset) == names.end()) {
    std::string available;
    for (const std::string& name : names) available += (available.empty() ? "" : ", ") + name;
    throw InputError(
        dataset, 0,
        fmt::format("--dataset: expected the name of a shipped sequence with a trajectory; "
                    "the shipped ones (`marglab datasets list`): {}",
                    available));
  }
  Sequence seq = loadSequence(dataset);
  if (!seq.hasTrajectory()) {
    throw InputError(dataset, 0,
                     "--dataset: this sequence has no trajectory (timestamps only): nothing to "
                     "render along");
  }
  return seq;
}

// Median sample rate of the real IMU, 200 Hz without one.
double imuRateHz(const Sequence& seq) {
  if (!seq.imu || seq.imu->size() < 2) return 200.0;
  return 1e9 / static_cast<double>(medianGapNs(seq.imu->t_ns));
}

// Frames: the real camera times inside the trajectory, from start_s after its first pose on.
std::vector<int64_t> selectFrames(const Sequence& seq, long long frames, double start_s) {
  const int64_t gt0 = seq.gt.t_ns.front(), gt1 = seq.gt.t_ns.back();
  const double span_s = 1e-9 * static_cast<double>(gt1 - gt0);
  if (!(start_s >= 0 && start_s < span_s)) {
    throw InputError(
        "--start", 0,
        fmt::format("expected a time in [0, {:.1f}) s (the ground truth of {})", span_s, seq.name));
  }
  const int64_t t_start = gt0 + static_cast<int64_t>(std::llround(start_s * 1e9));
  std::vector<int64_t> t;
  for (const int64_t c : seq.cam_t_ns) {
    if (c >= t_start && c <= gt1) t.push_back(c);
  }
  if (frames < 1 || static_cast<std::size_t>(frames) > t.size()) {
    throw InputError("--frames", 0,
                     fmt::format("expected a number of frames in [1, {}] ({} has {} camera frames "
                                 "inside its ground truth from {} s on), got {}",
                                 t.size(), seq.name, t.size(), start_s, frames));
  }
  t.resize(static_cast<std::size_t>(frames));
  return t;
}

void writeBytes(const fs::path& path, const void* data, std::size_t size) {
  std::ofstream out(path, std::ios::binary);
  out.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  out.close();
  if (!out)
    throw InputError(path.string(), 0, fmt::format("cannot write: {}", std::strerror(errno)));
}

void writeText(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  writeBytes(path, text.data(), text.size());
}

void copyFile(const fs::path& from, const fs::path& to) {
  fs::create_directories(to.parent_path());
  std::error_code ec;
  fs::copy_file(from, to, ec);
  if (ec)
    throw InputError(to.string(), 0,
                     fmt::format("cannot copy {}: {}", from.string(), ec.message()));
}

void writePng(const fs::path& path, const cv::Mat& image) {
  const std::vector<uint8_t> bytes = encodePng(image);
  writeBytes(path, bytes.data(), bytes.size());
}

}  // namespace

std::pair<int, int> kittiImageSize(const std::string& n) {
  if (n == "00" || n == "01" || n == "02") return {1241, 376};
  if (n == "03") return {1242, 375};
  if (n.size() == 2 && n[0] == '0' && n[1] >= '4' && n[1] <= '9') return {1226, 370};
  if (n == "10") return {1226, 370};
  return {0, 0};
}

RenderPlan planRendering(const std::string& dataset, long long frames, double start_s,
                         uint64_t seed) {
  RenderPlan plan;
  plan.sequence = shippedSequenceWithTrajectory(dataset);
  Sequence& seq = plan.sequence;
  if (seq.kind == DatasetKind::kKitti) {
    const auto [width, height] = kittiImageSize(seq.name.substr(seq.name.find('/') + 1));
    if (width == 0) {
      throw InputError(dataset, 0,
                       "--dataset: the recorded image size of this KITTI sequence is "
                       "not known (00–10 are)");
    }
    for (CameraCalib* cam : {&seq.calib.cam0, &seq.calib.cam1}) {
      cam->width = width;
      cam->height = height;
    }
  }
  plan.t_ns = selectFrames(seq, frames, start_s);
  plan.spline = std::make_unique<TrajectorySpline>(TrajectorySpline::fromSequence(seq));
  plan.world = makeWorld(*plan.spline, renderWorldOptions(seq.kind), seed);
  plan.render = defaultRenderOptions(seq.kind);
  plan.seed = seed;
  plan.start_s = start_s;
  return plan;
}

namespace {

// The temporary sibling folder "<target>.tmp-XXXXXX" (mkdtemp: a new name, never a folder of the
// user's that happens to match); removed unless renamed onto the output.
class TemporaryFolder {
 public:
  explicit TemporaryFolder(const fs::path& target) {
    std::string name = target.string() + ".tmp-XXXXXX";
    if (::mkdtemp(name.data()) == nullptr) {
      throw InputError(name, 0, std::string("cannot create the folder: ") + std::strerror(errno));
    }
    path_ = name;
  }
  ~TemporaryFolder() {
    std::error_code ec;
    if (!committed_) fs::remove_all(path_, ec);
  }
  TemporaryFolder(const TemporaryFolder&) = delete;
  TemporaryFolder& operator=(const TemporaryFolder&) = delete;
  const fs::path& path() const { return path_; }
  void renameOnto(const fs::path& target) {
    std::error_code ec;
    fs::rename(path_, target, ec);
    if (ec) {
      throw InputError(target.string(), 0,
                       fmt::format("cannot rename {} onto it: {}", path_.string(), ec.message()));
    }
    committed_ = true;
  }

 private:
  fs::path path_;
  bool committed_ = false;
};

// The output folder without a trailing separator; InputError when it exists and is not an empty
// folder.
fs::path checkedOutputFolder(const std::string& folder) {
  if (folder.empty()) throw UsageError("-o is empty: expected the folder to render into");
  fs::path path = fs::path(folder).lexically_normal();
  if (path.filename().empty()) path = path.parent_path();
  std::error_code ec;
  if (fs::exists(path, ec) && (!fs::is_directory(path, ec) || !fs::is_empty(path, ec))) {
    throw InputError(
        path.string(), 0,
        "-o: expected a new or empty folder for the rendered dataset; this path exists "
        "and is not an empty folder (nothing was written)");
  }
  return path;
}

// "radtan", "equidistant", "pinhole (rectified)".
std::string cameraModelName(const CameraCalib& cam) {
  return cam.distortion_model == "none" || cam.distortion_model.empty() ? "pinhole (rectified)"
                                                                        : cam.distortion_model;
}

std::string numbers(std::initializer_list<double> values, const char* separator) {
  std::string text;
  for (const double v : values) text += (text.empty() ? "" : separator) + fmt::format("{}", v);
  return text;
}

// The shipped ground-truth times from 1 s before the first frame to 1 s after the last.
std::vector<int64_t> groundTruthTimes(const RenderPlan& plan) {
  std::vector<int64_t> t;
  for (const int64_t g : plan.sequence.gt.t_ns) {
    if (g >= plan.t_ns.front() - kGtMarginNs && g <= plan.t_ns.back() + kGtMarginNs) {
      t.push_back(g);
    }
  }
  return t;
}

// Renders every frame; paths(k) names the left and right image of frame k.
void renderImages(const RenderPlan& plan,
                  const std::function<std::pair<fs::path, fs::path>(std::size_t)>& paths) {
  const WorldRenderer renderer(plan.world, plan.sequence.calib, plan.render);
  for (std::size_t k = 0; k < plan.t_ns.size(); ++k) {
    throwIfInterrupted();
    const RenderedFrame frame =
        renderer.render(plan.spline->evaluate(plan.t_ns[k]), static_cast<int>(k));
    const auto [left, right] = paths(k);
    writePng(left, frame.left);
    writePng(right, frame.right);
  }
}

// The IMU along the written ground truth's span, and imu0/{data.csv, sensor.yaml}.
SyntheticImu writeImu(const RenderPlan& plan, const std::vector<int64_t>& gt_t,
                      const fs::path& imu_dir) {
  const Sequence& seq = plan.sequence;
  const double rate_hz = imuRateHz(seq);
  ImuSynthOptions options;
  options.gravity_w = gravityWorld(seq.kind);
  // The IMU is synthesized over the written ground truth only.
  const TrajectoryWindow window(*plan.spline, gt_t.front(), gt_t.back());
  SyntheticImu imu = synthesizeImu(window, seq.imu_noise, rate_hz,
                                   SimRandom::subSeed(plan.seed, 0x696d75), options);
  std::string csv =
      "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
      "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";
  for (std::size_t i = 0; i < imu.imu.size(); ++i) {
    const Eigen::Vector3d& w = imu.imu.gyro[i];
    const Eigen::Vector3d& a = imu.imu.accel[i];
    csv += fmt::format("{},{}\n", imu.imu.t_ns[i],
                       numbers({w.x(), w.y(), w.z(), a.x(), a.y(), a.z()}, ","));
  }
  writeText(imu_dir / "data.csv", csv);
  const ImuNoise& n = seq.imu_noise;
  writeText(
      imu_dir / "sensor.yaml",
      fmt::format("# The noise imu0/data.csv was synthesized with (marglab datasets render).\n"
                  "sensor_type: imu\nrate_hz: {}\ngyroscope_noise_density: {}\n"
                  "gyroscope_random_walk: {}\naccelerometer_noise_density: {}\n"
                  "accelerometer_random_walk: {}\n",
                  rate_hz, n.gyro_noise_density, n.gyro_random_walk, n.accel_noise_density,
                  n.accel_random_walk));
  return imu;
}

// EuRoC state_groundtruth_estimate0 (17 columns) or TUM-VI mocap0 (8 columns).
void writeAslGroundTruth(const RenderPlan& plan, const std::vector<int64_t>& gt_t,
                         const SyntheticImu& imu, const fs::path& mav) {
  const bool euroc = plan.sequence.kind == DatasetKind::kEuroc;
  std::string csv =
      "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],"
      "q_RS_y [],q_RS_z []";
  if (euroc) {
    csv +=
        ",v_RS_R_x [m s^-1],v_RS_R_y [m s^-1],v_RS_R_z [m s^-1],b_w_RS_S_x [rad s^-1],"
        "b_w_RS_S_y [rad s^-1],b_w_RS_S_z [rad s^-1],b_a_RS_S_x [m s^-2],"
        "b_a_RS_S_y [m s^-2],b_a_RS_S_z [m s^-2]";
  }
  csv += "\n";
  std::size_t k = 0;  // the IMU sample at or before the pose: its true biases
  for (const int64_t t : gt_t) {
    const TrajectorySample s = plan.spline->evaluate(t);
    const Eigen::Quaterniond q(s.R_w_b);
    csv += fmt::format(
        "{},{}", t,
        numbers({s.p_w_b.x(), s.p_w_b.y(), s.p_w_b.z(), q.w(), q.x(), q.y(), q.z()}, ","));
    if (euroc) {
      while (k + 1 < imu.imu.size() && imu.imu.t_ns[k + 1] <= t) ++k;
      const Eigen::Vector3d &bg = imu.bias_gyro[k], &ba = imu.bias_accel[k];
      csv += "," + numbers({s.v_w.x(), s.v_w.y(), s.v_w.z(), bg.x(), bg.y(), bg.z(), ba.x(), ba.y(),
                            ba.z()},
                           ",");
    }
    csv += "\n";
  }
  writeText(mav / (euroc ? "state_groundtruth_estimate0" : "mocap0") / "data.csv", csv);
}

// A camera in EuRoC's sensor.yaml form (T_BS = T_b_c), for the TUM-VI folder's cameras.
std::string sensorYaml(const CameraCalib& cam, const char* name) {
  const Eigen::Matrix3d& R = cam.R_b_c;
  const Eigen::Vector3d& t = cam.t_b_c;
  std::string coefficients;
  for (const double k : cam.distortion) {
    coefficients += (coefficients.empty() ? "" : ", ") + fmt::format("{}", k);
  }
  return fmt::format(
      "# {} of a folder rendered by marglab (datasets render): the calibration of dso/camchain.yaml"
      "\nsensor_type: camera\nT_BS:\n  cols: 4\n  rows: 4\n  data: [{}, {}, {}, 0, 0, 0, 1]\n"
      "resolution: [{}, {}]\ncamera_model: pinhole\nintrinsics: [{}]\n"
      "distortion_model: {}\ndistortion_coefficients: [{}]\n",
      name, numbers({R(0, 0), R(0, 1), R(0, 2), t.x()}, ", "),
      numbers({R(1, 0), R(1, 1), R(1, 2), t.y()}, ", "),
      numbers({R(2, 0), R(2, 1), R(2, 2), t.z()}, ", "), cam.width, cam.height,
      numbers({cam.fx, cam.fy, cam.cx, cam.cy}, ", "), cam.distortion_model, coefficients);
}

// EuRoC: copies of cam{0,1}/sensor.yaml. TUM-VI: a copy of the Kalibr camchain, which the loader
// reads, where TUM-VI's export keeps it, and the same cameras as cam{0,1}/sensor.yaml.
void writeAslCalibration(const Sequence& seq, const fs::path& root) {
  if (seq.kind == DatasetKind::kTumvi) {
    copyFile(seq.calib_source, root / "dso" / "camchain.yaml");
    writeText(root / "mav0/cam0/sensor.yaml", sensorYaml(seq.calib.cam0, "cam0"));
    writeText(root / "mav0/cam1/sensor.yaml", sensorYaml(seq.calib.cam1, "cam1"));
    return;
  }
  for (const char* cam : {"0", "1"}) {
    std::string source = seq.calib_source;
    source.replace(source.find("{0,1}"), 5, cam);
    copyFile(source, root / "mav0" / (std::string("cam") + cam) / "sensor.yaml");
  }
}

void writeAslFolder(const RenderPlan& plan, const fs::path& root) {
  const fs::path mav = root / "mav0";
  std::string list = "#timestamp [ns],filename\n";
  for (const int64_t t : plan.t_ns) list += fmt::format("{},{}.png\n", t, t);
  for (const char* cam : {"cam0", "cam1"}) {
    fs::create_directories(mav / cam / "data");
    writeText(mav / cam / "data.csv", list);
  }
  writeAslCalibration(plan.sequence, root);
  const std::vector<int64_t> gt_t = groundTruthTimes(plan);
  const SyntheticImu imu = writeImu(plan, gt_t, mav / "imu0");
  writeAslGroundTruth(plan, gt_t, imu, mav);
  renderImages(plan, [&](std::size_t k) {
    const std::string file = fmt::format("{}.png", plan.t_ns[k]);
    return std::make_pair(mav / "cam0" / "data" / file, mav / "cam1" / "data" / file);
  });
}

// sequences/NN/{image_0, image_1, times.txt, calib.txt} and poses/NN.txt.
void writeKittiFolder(const RenderPlan& plan, const fs::path& root) {
  const std::string number = plan.sequence.name.substr(plan.sequence.name.find('/') + 1);
  const fs::path dir = root / "sequences" / number;
  std::string times, poses;
  for (const int64_t t : plan.t_ns) {
    times += fmt::format("{}.{:09d}\n", t / 1'000'000'000, t % 1'000'000'000);
    const TrajectorySample s = plan.spline->evaluate(t);
    const Eigen::Matrix3d& R = s.R_w_b;
    const Eigen::Vector3d& p = s.p_w_b;
    poses += numbers({R(0, 0), R(0, 1), R(0, 2), p.x(), R(1, 0), R(1, 1), R(1, 2), p.y(), R(2, 0),
                      R(2, 1), R(2, 2), p.z()},
                     " ") +
             "\n";
  }
  writeText(dir / "times.txt", times);
  writeText(root / "poses" / (number + ".txt"), poses);
  const std::string& calib = plan.sequence.calib_source;
  const bool gz = calib.size() > 3 && calib.compare(calib.size() - 3, 3, ".gz") == 0;
  copyFile(calib, dir / (gz ? "calib.txt.gz" : "calib.txt"));
  fs::create_directories(dir / "image_0");
  fs::create_directories(dir / "image_1");
  renderImages(plan, [&](std::size_t k) {
    const std::string file = fmt::format("{:06d}.png", k);
    return std::make_pair(dir / "image_0" / file, dir / "image_1" / file);
  });
}

std::string readme(const RenderPlan& plan, const std::string& command_line) {
  const Sequence& seq = plan.sequence;
  const CameraCalib& cam = seq.calib.cam0;
  return fmt::format(
      "Rendered by marglab {} (git {}):\n  {}\n\n"
      "Sequence: {} ({}), {} stereo frames at its real camera times from {} ns ({} s after its "
      "first ground-truth pose), {}x{} px, camera model {}; world and noise seed {}.\n\n"
      "The pixels are not camera images. A simulated world of points around the trajectory "
      "(core/sim/world.h) is drawn along the C2 spline through the sequence's ground truth: each "
      "visible point as a sprite of 4 Gaussian blobs centred exactly at its pixel through the "
      "real calibration (datasets/{}, copied), on a smooth background; from a random frame on a "
      "point is drawn "
      "with another texture (an outlier for the front-end). The sprite centre is the point's "
      "true pixel (core/frontend/world_render.h).\n"
      "{}.\n",
      MARGLAB_VERSION_STRING, MARGLAB_GIT_SHA, command_line, seq.name, seq.gt_source,
      plan.t_ns.size(), plan.t_ns.front(), plan.start_s, cam.width, cam.height,
      cameraModelName(cam), plan.seed,
      fs::path(seq.calib_source).lexically_relative(datasetsRoot()).string(),
      seq.kind == DatasetKind::kKitti
          ? "The ground truth (poses/) is that spline at the frames' times"
          : "The ground truth is that spline at the sequence's ground-truth times; the IMU "
            "(mav0/imu0) is synthesized along the same spline with the sequence's noise "
            "densities (core/sim/imu_synth.h)");
}

}  // namespace

RenderSummary writeRenderedFolder(const RenderPlan& plan, const std::string& folder,
                                  const std::string& command_line) {
  InterruptPolling polling;  // an interrupt unwinds, and the temporary folder is removed
  const fs::path target = checkedOutputFolder(folder);
  if (!target.parent_path().empty()) fs::create_directories(target.parent_path());
  TemporaryFolder temporary(target);
  if (plan.sequence.kind == DatasetKind::kKitti) {
    writeKittiFolder(plan, temporary.path());
  } else {
    writeAslFolder(plan, temporary.path());
  }
  writeText(temporary.path() / "README.txt", readme(plan, command_line));
  throwIfInterrupted();
  checkedOutputFolder(folder);  // nobody created it meanwhile
  temporary.renameOnto(target);
  RenderSummary summary;
  summary.frames = plan.t_ns.size();
  summary.width = plan.sequence.calib.cam0.width;
  summary.height = plan.sequence.calib.cam0.height;
  summary.camera_model = cameraModelName(plan.sequence.calib.cam0);
  return summary;
}

}  // namespace marglab
