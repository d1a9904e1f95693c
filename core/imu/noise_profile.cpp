#include "core/imu/noise_profile.h"

#include <fmt/core.h>

#include <algorithm>
#include <filesystem>
#include <string_view>
#include <vector>

#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/data/text_file.h"

namespace marglab {
namespace {

// A whole text file with the 1-based line of every character, for messages.
struct NumberedText {
  std::string text;
  std::vector<int> line_of;  // one per character of text

  explicit NumberedText(const std::string& path) {
    TextFile file(path);
    std::string_view line;
    while (file.nextLine(line)) {
      text.append(line);
      text.push_back('\n');
      line_of.insert(line_of.end(), line.size() + 1, file.lineNumber());
    }
  }
  int line(std::size_t pos) const { return pos < line_of.size() ? line_of[pos] : 0; }
};

// The list of numbers after `"key":` ("[a, b, c]"), all three equal and > 0; their value.
double isotropicDensity(const NumberedText& file, const std::string& path, const std::string& key) {
  const std::string quoted = "\"" + key + "\"";
  const std::size_t at = file.text.find(quoted);
  if (at == std::string::npos) {
    throw InputError(path, 0, fmt::format("expected the key \"{}\" (a Basalt calibration)", key));
  }
  const int line = file.line(at);
  if (file.text.find(quoted, at + 1) != std::string::npos) {
    throw InputError(path, file.line(file.text.find(quoted, at + 1)),
                     fmt::format("expected the key \"{}\" once", key));
  }
  const std::size_t open = file.text.find_first_not_of(" \t\n:", at + quoted.size());
  const std::size_t close = open == std::string::npos ? open : file.text.find(']', open);
  if (open == std::string::npos || file.text[open] != '[' || close == std::string::npos) {
    throw InputError(path, line, fmt::format("expected \"{}\": [x, y, z]", key));
  }
  std::vector<double> values;
  for (std::string_view field :
       splitFields(std::string_view(file.text).substr(open + 1, close - open - 1), ",")) {
    double v = 0;
    if (!tryParseDouble(trim(field), v)) {
      throw InputError(
          path, line,
          fmt::format("expected a number in \"{}\", got '{}'", key, std::string(trim(field))));
    }
    values.push_back(v);
  }
  const bool isotropic =
      values.size() == 3 && values[0] > 0 &&
      std::all_of(values.begin(), values.end(), [&](double v) { return v == values[0]; });
  if (!isotropic) {
    throw InputError(path, line,
                     fmt::format("expected \"{}\" to hold three equal values > 0 (marglab's IMU "
                                 "noise model is the same on every axis)",
                                 key));
  }
  return values[0];
}

}  // namespace

ImuNoise readBasaltImuNoise(const std::string& path) {
  const NumberedText file(path);
  ImuNoise noise;
  noise.gyro_noise_density = isotropicDensity(file, path, "gyro_noise_std");
  noise.gyro_random_walk = isotropicDensity(file, path, "gyro_bias_std");
  noise.accel_noise_density = isotropicDensity(file, path, "accel_noise_std");
  noise.accel_random_walk = isotropicDensity(file, path, "accel_bias_std");
  return noise;
}

std::string basaltCalibrationFile(DatasetKind kind) {
  const std::filesystem::path calib =
      std::filesystem::path(datasetsRoot()) / datasetKindName(kind) / "calib";
  switch (kind) {
    case DatasetKind::kEuroc:
      return (calib / "basalt_euroc_ds_calib.json").string();
    case DatasetKind::kTumvi:
      return (calib / "basalt_tumvi_512_ds_calib.json").string();
    case DatasetKind::kKitti:
      break;
  }
  throw InputError(calib.string(), 0,
                   "imu.noise_profile = \"basalt\": expected EuRoC or TUM-VI (KITTI has no IMU)");
}

ImuNoise profileImuNoise(const Sequence& sequence, ImuNoiseProfile profile) {
  if (profile == ImuNoiseProfile::kKalibr) return sequence.imu_noise;
  return readBasaltImuNoise(basaltCalibrationFile(sequence.kind));
}

}  // namespace marglab
