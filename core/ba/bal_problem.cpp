#include "core/ba/bal_problem.h"

#include <bzlib.h>
#include <fmt/core.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string_view>

#include "core/common/error.h"
#include "core/common/statistics.h"
#include "core/geometry/so3.h"

namespace marglab {
namespace {

std::string readFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw InputError(path, 0, "expected an existing regular file");
  }
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!in.good() && !in.eof()) throw InputError(path, 0, "expected a readable file");
  return bytes;
}

// Decompresses every bzip2 stream of `compressed` (pbzip2 writes several, back to back).
std::string bunzip2(const std::string& path, std::string& compressed) {
  std::string out;
  char chunk[1 << 16];
  bz_stream stream{};
  stream.next_in = compressed.data();
  stream.avail_in = static_cast<unsigned>(compressed.size());
  while (stream.avail_in > 0) {
    if (BZ2_bzDecompressInit(&stream, 0, 0) != BZ_OK) {
      throw InputError(path, 0, "expected a bzip2 stream (libbz2 failed to initialize)");
    }
    int rc = BZ_OK;
    while (rc == BZ_OK) {
      stream.next_out = chunk;
      stream.avail_out = sizeof(chunk);
      rc = BZ2_bzDecompress(&stream);
      out.append(chunk, sizeof(chunk) - stream.avail_out);
      if (rc == BZ_OK && stream.avail_in == 0 && stream.avail_out > 0) rc = BZ_UNEXPECTED_EOF;
    }
    BZ2_bzDecompressEnd(&stream);
    if (rc != BZ_STREAM_END) {
      throw InputError(path, 0, fmt::format("expected a valid bzip2 stream (libbz2 error {})", rc));
    }
  }
  return out;
}

// The whitespace-separated fields of a text, each with its 1-based line.
class FieldReader {
 public:
  FieldReader(std::string path, std::string_view text) : path_(std::move(path)), text_(text) {}

  template <typename T>
  T next(std::string_view what) {
    const std::string_view field = nextField(what);
    T value{};
    const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
    if (ec != std::errc() || end != field.data() + field.size()) {
      fail(fmt::format("expected {} (a number), got '{}'", what, shortToken(field)));
    }
    if constexpr (std::is_floating_point_v<T>) {
      if (!std::isfinite(value)) fail(fmt::format("expected a finite {}", what));
    }
    return value;
  }
  void expectEnd() {
    skipBlanks();
    if (pos_ < text_.size()) fail("expected the end of the file after the last point");
  }
  [[noreturn]] void fail(const std::string& message) const {
    throw InputError(path_, line_, message);
  }

 private:
  void skipBlanks() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
  }
  std::string_view nextField(std::string_view what) {
    skipBlanks();
    if (pos_ == text_.size()) fail(fmt::format("expected {}, got the end of the file", what));
    const size_t start = pos_;
    while (pos_ < text_.size() && !std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    return text_.substr(start, pos_ - start);
  }

  std::string path_;
  std::string_view text_;
  size_t pos_ = 0;
  int line_ = 1;
};

int readIndex(FieldReader& fields, std::string_view what, int count) {
  const int index = fields.next<int>(what);
  if (index < 0 || index >= count) {
    fields.fail(fmt::format("expected {} in [0, {}), got {}", what, count, index));
  }
  return index;
}

int readCount(FieldReader& fields, std::string_view what) {
  const int count = fields.next<int>(what);
  if (count <= 0) fields.fail(fmt::format("expected a positive {}, got {}", what, count));
  return count;
}

}  // namespace

std::string balProblemName(const std::string& path) {
  std::string name = std::filesystem::path(path).filename().string();
  for (std::string_view suffix : {".bz2", ".txt"}) {
    if (name.size() > suffix.size() &&
        name.compare(name.size() - suffix.size(), suffix.size(), suffix.data()) == 0) {
      name.resize(name.size() - suffix.size());
    }
  }
  return name;
}

std::string readPlainOrBzip2(const std::string& path) {
  std::string bytes = readFile(path);
  if (bytes.compare(0, 3, "BZh") == 0) return bunzip2(path, bytes);
  return bytes;
}

BalProblem loadBalProblem(const std::string& path) {
  const std::string text = readPlainOrBzip2(path);
  FieldReader fields(path, text);
  BalProblem problem;
  problem.name = balProblemName(path);
  const int num_cameras = readCount(fields, "the number of cameras");
  const int num_points = readCount(fields, "the number of points");
  const int num_observations = readCount(fields, "the number of observations");
  // Every field takes at least two bytes: a file too short for its counts is refused before
  // anything is allocated for them.
  const double fields_needed = 4.0 * num_observations + 9.0 * num_cameras + 3.0 * num_points;
  if (2.0 * fields_needed > static_cast<double>(text.size()) + 1.0) {
    fields.fail(
        fmt::format("expected {:.0f} numbers after the counts, but the file has only {} "
                    "bytes",
                    fields_needed, text.size()));
  }
  problem.observations.resize(static_cast<size_t>(num_observations));
  for (BalObservation& obs : problem.observations) {
    obs.camera = readIndex(fields, "a camera index", num_cameras);
    obs.point = readIndex(fields, "a point index", num_points);
    obs.z.x() = fields.next<double>("an observation x");
    obs.z.y() = fields.next<double>("an observation y");
  }
  problem.cameras.resize(static_cast<size_t>(num_cameras));
  for (Vec<double, 9>& camera : problem.cameras) {
    for (int i = 0; i < 9; ++i) camera[i] = fields.next<double>("a camera parameter");
  }
  problem.points.resize(static_cast<size_t>(num_points));
  for (Vec3<double>& point : problem.points) {
    for (int i = 0; i < 3; ++i) point[i] = fields.next<double>("a point coordinate");
  }
  fields.expectEnd();
  return problem;
}

namespace {

// A camera's centre C = −Rᵀt and back (t = −R C).
Vec3<double> cameraCentre(const Vec<double, 9>& camera) {
  return -(expSO3<double>(camera.head<3>()).transpose() * camera.segment<3>(3));
}
void setCameraCentre(const Vec3<double>& C, Vec<double, 9>* camera) {
  camera->segment<3>(3) = -(expSO3<double>(camera->head<3>()) * C);
}

}  // namespace

void normalizeBalProblem(BalProblem* problem, double scale) {
  Vec3<double> median;
  std::vector<double> values(problem->points.size());
  for (int k = 0; k < 3; ++k) {
    for (size_t i = 0; i < values.size(); ++i) values[i] = problem->points[i][k];
    median[k] = upperMedian(values);
  }
  for (size_t i = 0; i < values.size(); ++i) {
    values[i] = (problem->points[i] - median).lpNorm<1>();
  }
  const double s = scale / upperMedian(values);
  for (Vec3<double>& X : problem->points) X = s * (X - median);
  for (Vec<double, 9>& camera : problem->cameras) {
    setCameraCentre(s * (cameraCentre(camera) - median), &camera);
  }
}

void perturbBalProblem(BalProblem* problem, double sigma, std::uint64_t seed) {
  std::mt19937_64 engine(seed);
  std::normal_distribution<double> normal(0.0, sigma);
  const auto draw = [&] { return Vec3<double>(normal(engine), normal(engine), normal(engine)); };
  for (Vec<double, 9>& camera : problem->cameras) {
    setCameraCentre(cameraCentre(camera) + draw(), &camera);
  }
  for (Vec3<double>& X : problem->points) X += draw();
}

}  // namespace marglab
