#include "core/data/parsers.h"

#include <fmt/core.h>

#include <cmath>
#include <map>

#include "core/common/error.h"
#include "core/data/text_file.h"

namespace marglab {

namespace {

// Strictly increasing timestamps; `previous` is updated.
void checkIncreasing(int64_t t, int64_t& previous, bool first, const TextFile& file) {
  if (!first && t <= previous) {
    file.fail(
        fmt::format("expected timestamps increasing strictly, found {} after {}", t, previous));
  }
  previous = t;
}

// A pose appended to `trajectory` is checked against the step and speed limits, if any.
void checkStep(const Trajectory& trajectory, const PlausibilityLimits* limits,
               const TextFile& file) {
  const std::size_t n = trajectory.size();
  if (limits == nullptr || n < 2) return;
  const std::string problem =
      poseStepProblem(*limits, trajectory.t_ns[n - 2], trajectory.p_w_b[n - 2],
                      trajectory.t_ns[n - 1], trajectory.p_w_b[n - 1]);
  if (!problem.empty()) file.fail(problem);
}

void checkColumns(const std::vector<std::string_view>& fields, std::size_t expected,
                  const TextFile& file, std::string_view layout) {
  if (fields.size() != expected) {
    file.fail(fmt::format("expected {} columns ({}), found {}", expected, layout, fields.size()));
  }
}

Eigen::Quaterniond unitQuaternion(double w, double x, double y, double z, const TextFile& file) {
  Eigen::Quaterniond q(w, x, y, z);
  const double norm = q.norm();
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    file.fail(fmt::format("expected a unit quaternion (|norm - 1| <= {:g}), found norm {:.6g}",
                          kQuaternionNormTolerance, norm));
  }
  return q.normalized();
}

bool isRotation(const Eigen::Matrix3d& R) {
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <=
             kRotationTolerance &&
         R.determinant() > 0;
}

std::string columnName(std::size_t index, const char* const* names) {
  return fmt::format("column {} ({})", index + 1, names[index]);
}

// ----- A minimal YAML reader, enough for EuRoC sensor.yaml and Kalibr chains
// ----------------------
//
// Produces "parent.child" → value text (with its line). Block sequences of inline lists
// ("- [a, b, c, d]") under a key are concatenated into that key's value; bracketed lists may span
// lines. Anchors, multi-line strings and flow maps are not supported (not used by these files).

struct YamlValue {
  std::string text;
  int line = 0;
};

class FlatYaml {
 public:
  explicit FlatYaml(const std::string& path) : path_(path) {
    TextFile file(path);
    std::vector<std::pair<int, std::string>> parents;  // (indent, key)
    std::string* open_value = nullptr;                 // a '[' list still open
    int open_depth = 0;
    std::string_view raw;
    while (file.nextLine(raw)) {
      std::string_view line = raw.substr(0, raw.find('#'));
      if (trim(line).empty() || trim(line).front() == '%' || trim(line) == "---") continue;
      if (open_value != nullptr) {
        appendList(*open_value, trim(line), open_depth);
        if (open_depth == 0) open_value = nullptr;
        continue;
      }
      const int indent = static_cast<int>(line.find_first_not_of(' '));
      std::string_view content = trim(line);
      if (content.front() == '-') {
        if (parents.empty()) file.fail("expected a key before the list item");
        YamlValue& value = values_[joinKey(parents)];
        if (value.line == 0) value.line = file.lineNumber();
        open_depth = 0;
        appendList(value.text, trim(content.substr(1)), open_depth);
        if (open_depth > 0) open_value = &value.text;
        continue;
      }
      const std::size_t colon = content.find(':');
      if (colon == std::string_view::npos) file.fail("expected 'key: value'");
      while (!parents.empty() && parents.back().first >= indent) parents.pop_back();
      const std::string key(trim(content.substr(0, colon)));
      const std::string_view rest = trim(content.substr(colon + 1));
      if (rest.empty()) {
        parents.emplace_back(indent, key);
        continue;
      }
      parents.emplace_back(indent, key);
      YamlValue& value = values_[joinKey(parents)];
      parents.pop_back();
      value.line = file.lineNumber();
      value.text.clear();
      open_depth = 0;
      appendList(value.text, rest, open_depth);
      if (open_depth > 0) open_value = &value.text;
    }
    if (open_value != nullptr) file.fail("expected ']' closing the list");
  }

  const YamlValue* find(const std::string& key) const {
    const auto it = values_.find(key);
    return it == values_.end() ? nullptr : &it->second;
  }

  const YamlValue& get(const std::string& key) const {
    const YamlValue* value = find(key);
    if (value == nullptr) throw InputError(path_, 0, fmt::format("expected the key '{}'", key));
    return *value;
  }

  std::string string(const std::string& key) const {
    std::string text = get(key).text;
    if (text.size() >= 2 && (text.front() == '"' || text.front() == '\'')) {
      text = text.substr(1, text.size() - 2);
    }
    return text;
  }

  // All numbers of a (possibly nested) list value; `count` < 0 accepts any count.
  std::vector<double> numbers(const std::string& key, int count) const {
    const YamlValue& value = get(key);
    std::string text = value.text;
    for (char& c : text) {
      if (c == '[' || c == ']' || c == ',') c = ' ';
    }
    std::vector<double> result;
    for (std::string_view token : splitFields(text, " \t")) {
      double x = 0;
      if (!tryParseDouble(token, x) || !std::isfinite(x)) {
        throw InputError(
            path_, value.line,
            fmt::format("expected finite numbers in '{}', found '{}'", key, shortToken(token)));
      }
      result.push_back(x);
    }
    if (count >= 0 && static_cast<int>(result.size()) != count) {
      throw InputError(
          path_, value.line,
          fmt::format("expected {} numbers in '{}', found {}", count, key, result.size()));
    }
    return result;
  }

  // A 4×4 homogeneous rigid transform (row-major), checked.
  void transform(const std::string& key, Eigen::Matrix3d& R, Eigen::Vector3d& t) const {
    const std::vector<double> v = numbers(key, 16);
    Eigen::Matrix4d T;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) T(r, c) = v[4 * r + c];
    }
    R = T.topLeftCorner<3, 3>();
    t = T.topRightCorner<3, 1>();
    if (!isRotation(R) || !T.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1))) {
      throw InputError(path_, get(key).line,
                       fmt::format("expected a rigid transform in '{}' (orthonormal rotation, "
                                   "det +1, last row 0 0 0 1)",
                                   key));
    }
    R = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  }

  const std::string& path() const { return path_; }

 private:
  static std::string joinKey(const std::vector<std::pair<int, std::string>>& parents) {
    std::string key;
    for (const auto& [indent, name] : parents) key += (key.empty() ? "" : ".") + name;
    return key;
  }

  static void appendList(std::string& value, std::string_view text, int& depth) {
    if (!value.empty()) value += ' ';
    value += text;
    for (char c : text) depth += (c == '[') - (c == ']');
  }

  std::string path_;
  std::map<std::string, YamlValue> values_;
};

void readPinholeIntrinsics(const FlatYaml& yaml, const std::string& prefix, CameraCalib& cam) {
  const std::vector<double> k = yaml.numbers(prefix + "intrinsics", 4);
  cam.fx = k[0];
  cam.fy = k[1];
  cam.cx = k[2];
  cam.cy = k[3];
  if (cam.fx <= 0 || cam.fy <= 0) {
    throw InputError(yaml.path(), yaml.get(prefix + "intrinsics").line,
                     "expected positive focal lengths");
  }
  // Checked before the cast to int: a double outside int's range makes the cast undefined.
  constexpr double kMaxPixels = 1 << 16;
  const std::vector<double> size = yaml.numbers(prefix + "resolution", 2);
  for (double n : size) {
    if (!(n >= 1 && n <= kMaxPixels && n == std::floor(n))) {
      throw InputError(yaml.path(), yaml.get(prefix + "resolution").line,
                       fmt::format("expected a resolution of whole numbers in [1, {}], found {}",
                                   kMaxPixels, n));
    }
  }
  cam.width = static_cast<int>(size[0]);
  cam.height = static_cast<int>(size[1]);
}

}  // namespace

Trajectory readTumTrajectory(const std::string& path, const PlausibilityLimits* limits) {
  static const char* const kNames[] = {"t [s]", "x", "y", "z", "qx", "qy", "qz", "qw"};
  TextFile file(path);
  Trajectory trajectory;
  int64_t previous = 0;
  std::string_view line;
  while (file.nextDataLine(line)) {
    const auto f = splitFields(line, " \t");
    checkColumns(f, 8, file, "t[s] x y z qx qy qz qw");
    const int64_t t = parseSecondsToNs(f[0], file, columnName(0, kNames));
    checkIncreasing(t, previous, trajectory.empty(), file);
    double v[8];
    for (int i = 1; i < 8; ++i) v[i] = parseDouble(f[i], file, columnName(i, kNames));
    trajectory.push_back(t, Eigen::Vector3d(v[1], v[2], v[3]),
                         unitQuaternion(v[7], v[4], v[5], v[6], file));
    checkStep(trajectory, limits, file);
  }
  if (trajectory.empty()) file.fail("expected at least one pose (the file has no data lines)");
  return trajectory;
}

AslGroundTruth readAslGroundTruth(const std::string& path, const PlausibilityLimits* limits) {
  static const char* const kNames[] = {"t [ns]", "p_x",  "p_y",  "p_z",  "q_w", "q_x",
                                       "q_y",    "q_z",  "v_x",  "v_y",  "v_z", "bw_x",
                                       "bw_y",   "bw_z", "ba_x", "ba_y", "ba_z"};
  TextFile file(path);
  AslGroundTruth gt;
  std::size_t columns = 0;
  int64_t previous = 0;
  std::string_view line;
  while (file.nextDataLine(line)) {
    const auto f = splitFields(line, ",");
    if (columns == 0) {
      if (f.size() != 8 && f.size() != 17) {
        file.fail(fmt::format(
            "expected 8 columns (t, p xyz, q wxyz) or 17 (+ v, b_w, b_a), found {}", f.size()));
      }
      columns = f.size();
      if (columns == 17) gt.state.emplace();
    }
    checkColumns(f, columns, file,
                 columns == 8 ? "t, p xyz, q wxyz" : "t, p xyz, q wxyz, v xyz, b_w xyz, b_a xyz");
    const int64_t t = parseInt64(f[0], file, columnName(0, kNames));
    checkIncreasing(t, previous, gt.trajectory.empty(), file);
    double v[17];
    for (std::size_t i = 1; i < columns; ++i) v[i] = parseDouble(f[i], file, columnName(i, kNames));
    gt.trajectory.push_back(t, Eigen::Vector3d(v[1], v[2], v[3]),
                            unitQuaternion(v[4], v[5], v[6], v[7], file));
    checkStep(gt.trajectory, limits, file);
    if (gt.state) {
      gt.state->v_w_b.emplace_back(v[8], v[9], v[10]);
      gt.state->bias_gyro.emplace_back(v[11], v[12], v[13]);
      gt.state->bias_accel.emplace_back(v[14], v[15], v[16]);
    }
  }
  if (gt.trajectory.empty()) file.fail("expected at least one pose (the file has no data lines)");
  return gt;
}

ImuData readAslImu(const std::string& path, const PlausibilityLimits* limits) {
  static const char* const kNames[] = {"t [ns]", "w_x", "w_y", "w_z", "a_x", "a_y", "a_z"};
  TextFile file(path);
  ImuData imu;
  int64_t previous = 0;
  std::string_view line;
  while (file.nextDataLine(line)) {
    const auto f = splitFields(line, ",");
    checkColumns(f, 7, file, "t[ns], w xyz, a xyz");
    const int64_t t = parseInt64(f[0], file, columnName(0, kNames));
    const int64_t t_prev = previous;
    checkIncreasing(t, previous, imu.empty(), file);
    double v[7];
    for (int i = 1; i < 7; ++i) v[i] = parseDouble(f[i], file, columnName(i, kNames));
    if (limits != nullptr) {
      const std::string problem =
          imuSampleProblem(*limits, imu.empty(), t_prev, t, Eigen::Vector3d(v[1], v[2], v[3]),
                           Eigen::Vector3d(v[4], v[5], v[6]));
      if (!problem.empty()) file.fail(problem);
    }
    imu.t_ns.push_back(t);
    imu.gyro.emplace_back(v[1], v[2], v[3]);
    imu.accel.emplace_back(v[4], v[5], v[6]);
  }
  if (imu.empty()) file.fail("expected at least one IMU sample (the file has no data lines)");
  return imu;
}

std::vector<int64_t> readTimestampList(const std::string& path) {
  TextFile file(path);
  std::vector<int64_t> stamps;
  int64_t previous = 0;
  std::string_view line;
  while (file.nextDataLine(line)) {
    const auto f = splitFields(line, ",");
    if (f.size() != 1 && f.size() != 2) {
      file.fail(fmt::format("expected one timestamp [ns] or 'timestamp,filename', found {} columns",
                            f.size()));
    }
    const int64_t t = parseInt64(f[0], file, "column 1 (t [ns])");
    checkIncreasing(t, previous, stamps.empty(), file);
    stamps.push_back(t);
  }
  if (stamps.empty()) file.fail("expected at least one timestamp (the file has no data lines)");
  return stamps;
}

CameraCalib readEurocSensorYaml(const std::string& path) {
  const FlatYaml yaml(path);
  CameraCalib cam;
  const std::string model = yaml.string("camera_model");
  if (model != "pinhole") {
    throw InputError(path, yaml.get("camera_model").line,
                     fmt::format("expected camera_model 'pinhole', found '{}'", shortToken(model)));
  }
  readPinholeIntrinsics(yaml, "", cam);
  yaml.transform("T_BS.data", cam.R_b_c, cam.t_b_c);
  cam.distortion_model = yaml.string("distortion_model");
  if (cam.distortion_model == "radial-tangential") cam.distortion_model = "radtan";
  cam.distortion = yaml.numbers("distortion_coefficients", -1);
  return cam;
}

StereoCalib readKalibrCamchain(const std::string& path) {
  const FlatYaml yaml(path);
  StereoCalib stereo;
  for (int i = 0; i < 2; ++i) {
    const std::string prefix = fmt::format("cam{}.", i);
    CameraCalib& cam = i == 0 ? stereo.cam0 : stereo.cam1;
    readPinholeIntrinsics(yaml, prefix, cam);
    if (yaml.find(prefix + "T_imu_cam") != nullptr) {
      yaml.transform(prefix + "T_imu_cam", cam.R_b_c, cam.t_b_c);
    } else {
      Eigen::Matrix3d R_c_b;
      Eigen::Vector3d t_c_b;
      yaml.transform(prefix + "T_cam_imu", R_c_b, t_c_b);
      cam.R_b_c = R_c_b.transpose();
      cam.t_b_c = -(R_c_b.transpose() * t_c_b);
    }
    cam.distortion_model = yaml.find(prefix + "distortion_model") != nullptr
                               ? yaml.string(prefix + "distortion_model")
                               : "none";
    if (yaml.find(prefix + "distortion_coeffs") != nullptr) {
      cam.distortion = yaml.numbers(prefix + "distortion_coeffs", -1);
    }
  }
  return stereo;
}

ImuNoise readKalibrImuNoise(const std::string& path) {
  const FlatYaml yaml(path);
  const auto value = [&](const std::string& name) {
    const std::string key = yaml.find("imu0." + name) != nullptr ? "imu0." + name : name;
    const double x = yaml.numbers(key, 1)[0];
    if (!(x > 0)) {
      throw InputError(path, yaml.get(key).line, fmt::format("expected '{}' > 0", name));
    }
    return x;
  };
  ImuNoise noise;
  noise.gyro_noise_density = value("gyroscope_noise_density");
  noise.gyro_random_walk = value("gyroscope_random_walk");
  noise.accel_noise_density = value("accelerometer_noise_density");
  noise.accel_random_walk = value("accelerometer_random_walk");
  return noise;
}

std::vector<int64_t> readKittiTimes(const std::string& path) {
  TextFile file(path);
  std::vector<int64_t> stamps;
  int64_t previous = 0;
  std::string_view line;
  while (file.nextDataLine(line)) {
    const auto f = splitFields(line, " \t");
    checkColumns(f, 1, file, "t [s]");
    const int64_t t = parseSecondsToNs(f[0], file, "column 1 (t [s])");
    checkIncreasing(t, previous, stamps.empty(), file);
    stamps.push_back(t);
  }
  if (stamps.empty()) file.fail("expected at least one time (the file has no data lines)");
  return stamps;
}

Trajectory readKittiPoses(const std::string& path, const std::vector<int64_t>& t_ns,
                          const PlausibilityLimits* limits) {
  TextFile file(path);
  Trajectory trajectory;
  std::string_view line;
  while (file.nextDataLine(line)) {
    const auto f = splitFields(line, " \t");
    checkColumns(f, 12, file, "rows 0-2 of T_w_cam0, row-major");
    if (trajectory.size() == t_ns.size()) {
      file.fail(fmt::format("expected {} poses, one per line of times.txt; this is one more",
                            t_ns.size()));
    }
    Eigen::Matrix<double, 3, 4> T;
    for (int i = 0; i < 12; ++i) {
      T(i / 4, i % 4) = parseDouble(f[i], file, fmt::format("column {}", i + 1));
    }
    const Eigen::Matrix3d R = T.leftCols<3>();
    if (!isRotation(R)) {
      file.fail(
          fmt::format("expected a rotation (|RᵀR − I| <= {:g}, det +1), found |RᵀR − I| = "
                      "{:.3g}, det {:.6g}",
                      kRotationTolerance,
                      (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(),
                      R.determinant()));
    }
    trajectory.push_back(t_ns[trajectory.size()], T.col(3), Eigen::Quaterniond(R).normalized());
    checkStep(trajectory, limits, file);
  }
  if (trajectory.size() != t_ns.size()) {
    file.fail(fmt::format("expected {} poses, one per line of times.txt, found {}", t_ns.size(),
                          trajectory.size()));
  }
  return trajectory;
}

StereoCalib readKittiCalib(const std::string& path, int width, int height) {
  TextFile file(path);
  std::map<std::string, Eigen::Matrix<double, 3, 4>> P;
  std::map<std::string, int> lines;
  std::string_view line;
  while (file.nextDataLine(line)) {
    const auto f = splitFields(line, " \t");
    if (f.empty() || f[0].empty() || f[0].back() != ':') file.fail("expected 'NAME: values'");
    const std::string name(f[0].substr(0, f[0].size() - 1));
    if (name.size() != 2 || name[0] != 'P') continue;  // Tr: (velodyne) and others are not needed
    checkColumns(f, 13, file, "Pn: then 12 values of the 3x4 projection, row-major");
    Eigen::Matrix<double, 3, 4> M;
    for (int i = 0; i < 12; ++i) {
      M(i / 4, i % 4) = parseDouble(f[i + 1], file, fmt::format("value {} of {}", i + 1, name));
    }
    P[name] = M;
    lines[name] = file.lineNumber();
  }
  for (const char* name : {"P0", "P1"}) {
    if (P.count(name) == 0) throw InputError(path, 0, fmt::format("expected a line '{}:'", name));
  }
  StereoCalib stereo;
  for (int i = 0; i < 2; ++i) {
    const std::string name = i == 0 ? "P0" : "P1";
    const Eigen::Matrix<double, 3, 4>& M = P[name];
    CameraCalib& cam = i == 0 ? stereo.cam0 : stereo.cam1;
    if (!(M(0, 0) > 0) || !(M(1, 1) > 0) || M(2, 2) != 1.0) {
      throw InputError(
          path, lines[name],
          fmt::format("expected a rectified projection in {} (fx, fy > 0, P[2,2] = 1)", name));
    }
    cam.fx = M(0, 0);
    cam.fy = M(1, 1);
    cam.cx = M(0, 2);
    cam.cy = M(1, 2);
    cam.width = width;
    cam.height = height;
    cam.distortion_model = "none";
    // P_i = K [I | K⁻¹ p_i]: camera i sees p_ci = p_c0 + K⁻¹ p_i, i.e. its centre is at −K⁻¹ p_i.
    const double tx = M(0, 3) / M(0, 0);
    cam.t_b_c = Eigen::Vector3d(-tx, 0, 0);
  }
  return stereo;
}

}  // namespace marglab
