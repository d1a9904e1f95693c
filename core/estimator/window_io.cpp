#include "core/estimator/window_io.h"

#include <fmt/core.h>
#include <unistd.h>
#include <zlib.h>

#include <cerrno>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string_view>

#include "core/common/atomic_file.h"
#include "core/common/error.h"

namespace marglab {
namespace {

class Writer {
 public:
  void word(std::string_view w) {
    out_.append(w);
    out_.push_back(' ');
  }
  void integer(int64_t v) { word(std::to_string(v)); }
  void number(double v) {
    char buf[40];
    std::snprintf(buf, sizeof(buf), "%.17g", v);
    word(buf);
  }
  template <typename Derived>
  void numbers(const Eigen::MatrixBase<Derived>& m) {
    for (Eigen::Index i = 0; i < m.rows(); ++i) {
      for (Eigen::Index j = 0; j < m.cols(); ++j) number(m(i, j));
    }
  }
  void pose(const SE3<double>& T) {
    numbers(T.unitQuaternion().coeffs());
    numbers(T.translation());
  }
  void matrix(const MatXd& m) {
    integer(m.rows());
    integer(m.cols());
    numbers(m);
    newline();
  }
  void newline() { out_.back() = '\n'; }
  std::string& text() { return out_; }

 private:
  std::string out_;
};

class Reader {
 public:
  Reader(std::string text, std::string path) : text_(std::move(text)), path_(std::move(path)) {}
  std::string word() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    const size_t start = pos_;
    while (pos_ < text_.size() && !std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    if (start == pos_) fail("unexpected end of file");
    return text_.substr(start, pos_ - start);
  }
  void expect(const std::string& keyword) {
    const std::string w = word();
    if (w != keyword) fail(fmt::format("expected '{}', found '{}'", keyword, w));
  }
  int64_t integer() {
    const std::string w = word();
    char* end = nullptr;
    const long long v = std::strtoll(w.c_str(), &end, 10);
    if (*end != '\0') fail(fmt::format("'{}' is not an integer", w));
    return v;
  }
  double number() {
    const std::string w = word();
    char* end = nullptr;
    const double v = std::strtod(w.c_str(), &end);
    if (*end != '\0') fail(fmt::format("'{}' is not a number", w));
    return v;
  }
  template <int R, int C>
  Mat<double, R, C> fixed() {
    Mat<double, R, C> m;
    for (int i = 0; i < R; ++i) {
      for (int j = 0; j < C; ++j) m(i, j) = number();
    }
    return m;
  }
  SE3<double> pose() {
    Eigen::Quaterniond q;
    q.coeffs() = fixed<4, 1>();
    const Eigen::Vector3d t = fixed<3, 1>();
    // Exact: the stored quaternion is already unit; normalizing again could change its bits.
    SE3<double> T(q, t);
    const_cast<Eigen::Quaterniond&>(T.unitQuaternion()) = q;
    return T;
  }
  MatXd matrix() {
    const int64_t rows = integer(), cols = integer();
    // Every entry takes at least one byte of the rest of the file; checked without multiplying,
    // which could overflow, and before the allocation, which a corrupt size would make huge.
    if (rows < 0 || cols < 0 || (rows > 0 && cols > static_cast<int64_t>(remaining()) / rows)) {
      fail("bad matrix size");
    }
    MatXd m(rows, cols);
    for (int64_t i = 0; i < rows; ++i) {
      for (int64_t j = 0; j < cols; ++j) m(i, j) = number();
    }
    return m;
  }
  // A matrix with one column (an Eigen assignment to a vector would otherwise assert).
  VecXd vector() {
    MatXd m = matrix();
    if (m.cols() != 1)
      fail(fmt::format("expected a vector (1 column), found {} columns", m.cols()));
    return m.col(0);
  }
  std::string bytes(size_t n) {
    if (pos_ >= text_.size() || text_[pos_] != '\n' || pos_ + 1 + n > text_.size()) {
      fail("truncated config");
    }
    std::string out = text_.substr(pos_ + 1, n);
    pos_ += 1 + n;
    return out;
  }
  size_t count(int64_t max = 100'000'000) {
    const int64_t n = integer();
    // Each counted item takes at least one byte of the rest of the file: a larger count is a
    // corrupt file and must not size an allocation (resize before reading the items).
    if (n < 0 || n > max || static_cast<uint64_t>(n) > remaining()) {
      fail(fmt::format("bad count {}", n));
    }
    return static_cast<size_t>(n);
  }
  size_t remaining() const { return text_.size() - pos_; }
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(path_, 0, fmt::format("window file (byte {}): {}", pos_, what));
  }

 private:
  std::string text_;
  std::string path_;
  size_t pos_ = 0;
};

PinholeCamera<double> readCamera(Reader& in) {
  PinholeCamera<double> c;
  c.fx = in.number();
  c.fy = in.number();
  c.cx = in.number();
  c.cy = in.number();
  c.width = static_cast<int>(in.integer());
  c.height = static_cast<int>(in.integer());
  return c;
}

void writeCamera(Writer& out, const PinholeCamera<double>& c) {
  out.number(c.fx);
  out.number(c.fy);
  out.number(c.cx);
  out.number(c.cy);
  out.integer(c.width);
  out.integer(c.height);
}

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Sections of the text format, in file order.
void writeHeader(Writer& out, const WindowSnapshot& w) {
  out.word("marglab-window");
  out.integer(1);
  out.newline();
  out.word("dataset");
  out.word(w.dataset.empty() ? "-" : w.dataset);
  out.word("variant");
  out.word(w.variant.empty() ? "-" : w.variant);
  out.word("frame_index");
  out.integer(w.frame_index);
  out.word("mode");
  out.word(w.vio ? "vio" : "vo");
  out.newline();
  const std::string config = w.config.toToml();
  out.word("config");
  out.integer(static_cast<int64_t>(config.size()));
  out.newline();
  out.text() += config;
  out.text() += "\n";
  out.word("rig");
  writeCamera(out, w.rig.cam0);
  writeCamera(out, w.rig.cam1);
  out.pose(w.rig.T_i_c0);
  out.pose(w.rig.T_i_c1);
  out.newline();
}

void writeImu(Writer& out, const WindowSnapshot& w) {
  out.word("imu");
  out.number(w.imu_noise.gyro_noise_density);
  out.number(w.imu_noise.gyro_random_walk);
  out.number(w.imu_noise.accel_noise_density);
  out.number(w.imu_noise.accel_random_walk);
  out.number(w.imu_sample_period_s);
  out.numbers(w.g_w);
  out.integer(static_cast<int64_t>(w.imu.size()));
  out.newline();
  for (size_t k = 0; k < w.imu.size(); ++k) {
    out.integer(w.imu.t_ns[k]);
    out.numbers(w.imu.gyro[k]);
    out.numbers(w.imu.accel[k]);
    out.newline();
  }
}

void writeStates(Writer& out, const WindowSnapshot& w) {
  out.word("failed_solves");
  out.integer(w.failed_solves);
  out.newline();
  out.word("frames");
  out.integer(static_cast<int64_t>(w.frames.size()));
  out.newline();
  for (const auto& f : w.frames) {
    out.integer(f.id);
    out.integer(f.t_ns);
    out.integer(f.is_keyframe);
    out.integer(f.linearized);
    out.integer(f.has_speed_bias);
    out.integer(f.speed_bias_linearized);
    out.pose(f.T_w_i);
    out.pose(f.T_w_i_lin);
    out.numbers(f.speed_bias);
    out.numbers(f.speed_bias_lin);
    out.newline();
  }
  out.word("landmarks");
  out.integer(static_cast<int64_t>(w.landmarks.size()));
  out.newline();
  for (const auto& lm : w.landmarks) {
    out.integer(lm.id);
    out.integer(lm.host);
    out.numbers(lm.param);
    out.integer(static_cast<int64_t>(lm.obs.size()));
    for (const auto& o : lm.obs) {
      out.integer(o.frame);
      out.numbers(o.uv0);
      out.integer(o.has_right);
      out.numbers(o.uv1);
    }
    out.newline();
  }
  out.word("imu_links");
  out.integer(static_cast<int64_t>(w.imu_links.size()));
  out.newline();
  for (const auto& l : w.imu_links) {
    out.integer(l.from);
    out.integer(l.to);
    out.numbers(l.bias_gyro_lin);
    out.numbers(l.bias_accel_lin);
    out.newline();
  }
}

void writePrior(Writer& out, const WindowSnapshot& w) {
  out.word("prior");
  out.word(w.prior_representation == Representation::kSqrt ? "sqrt" : "hessian");
  out.integer(static_cast<int64_t>(w.prior_blocks.size()));
  out.newline();
  for (const auto& b : w.prior_blocks) {
    out.integer(b.var.frame_id);
    out.integer(static_cast<int>(b.var.block));
    out.integer(b.offset);
    out.pose(b.T0);
    out.numbers(b.sb0);
    out.newline();
  }
  out.matrix(w.prior_J);
  out.matrix(w.prior_r);
  out.matrix(w.prior_H);
  out.matrix(w.prior_b);
  out.number(w.prior_c);
  out.newline();
}

void writeAfter(Writer& out, const WindowSnapshot& w) {
  out.word("after");
  out.integer(w.after.present);
  if (w.after.present) {
    out.integer(w.after.lm_iterations);
    out.number(w.after.cost_initial);
    out.number(w.after.cost_final);
    out.newline();
    out.word("frames");
    out.integer(static_cast<int64_t>(w.after.frames.size()));
    out.newline();
    for (const auto& f : w.after.frames) {
      out.integer(f.id);
      out.pose(f.T_w_i);
      out.numbers(f.speed_bias);
      out.newline();
    }
    out.word("landmarks");
    out.integer(static_cast<int64_t>(w.after.landmarks.size()));
    out.newline();
    for (const auto& lm : w.after.landmarks) {
      out.integer(lm.id);
      out.numbers(lm.param);
      out.newline();
    }
  } else {
    out.newline();
  }
  out.word("end");
  out.newline();
}

// The text, gzip-compressed for a .gz path, through an AtomicFile (gzip writes to a duplicate
// of its descriptor, so that the AtomicFile still syncs and renames it).
void writeText(const std::string& text, const std::string& path) {
  AtomicFile file(path);
  if (endsWith(path, ".gz")) {
    const int fd = ::dup(file.fd());
    gzFile f = fd < 0 ? nullptr : gzdopen(fd, "wb9");
    if (f == nullptr) {
      if (fd >= 0) ::close(fd);
      throw InputError(path, 0, "cannot write the window file " + file.temporaryPath());
    }
    const int n = gzwrite(f, text.data(), static_cast<unsigned>(text.size()));
    const int error = errno;
    if (gzclose(f) != Z_OK || n != static_cast<int>(text.size())) {
      throw InputError(path, 0,
                       "cannot write the window file " + file.temporaryPath() + ": " +
                           std::strerror(error != 0 ? error : EIO));
    }
  } else {
    file.write(text);
  }
  file.commit();
}

void readHeader(Reader& in, const std::string& path, WindowSnapshot& w) {
  in.expect("marglab-window");
  if (in.integer() != 1) in.fail("unsupported format version");
  in.expect("dataset");
  w.dataset = in.word();
  in.expect("variant");
  w.variant = in.word();
  in.expect("frame_index");
  w.frame_index = in.integer();
  in.expect("mode");
  const std::string mode = in.word();
  if (mode != "vo" && mode != "vio") in.fail("mode must be vo or vio");
  w.vio = mode == "vio";
  in.expect("config");
  const std::string config = in.bytes(in.count());
  w.config = EstimatorSettings{};
  w.config.loadTomlString(config, path + " [config]");
  in.expect("rig");
  w.rig.cam0 = readCamera(in);
  w.rig.cam1 = readCamera(in);
  w.rig.T_i_c0 = in.pose();
  w.rig.T_i_c1 = in.pose();
}

void readImu(Reader& in, WindowSnapshot& w) {
  in.expect("imu");
  w.imu_noise.gyro_noise_density = in.number();
  w.imu_noise.gyro_random_walk = in.number();
  w.imu_noise.accel_noise_density = in.number();
  w.imu_noise.accel_random_walk = in.number();
  w.imu_sample_period_s = in.number();
  w.g_w = in.fixed<3, 1>();
  const size_t n_imu = in.count();
  for (size_t k = 0; k < n_imu; ++k) {
    w.imu.t_ns.push_back(in.integer());
    w.imu.gyro.push_back(in.fixed<3, 1>());
    w.imu.accel.push_back(in.fixed<3, 1>());
  }
}

void readStates(Reader& in, WindowSnapshot& w) {
  in.expect("failed_solves");
  w.failed_solves = static_cast<int>(in.integer());
  in.expect("frames");
  w.frames.resize(in.count(100000));
  for (auto& fs : w.frames) {
    fs.id = in.integer();
    fs.t_ns = in.integer();
    fs.is_keyframe = in.integer() != 0;
    fs.linearized = in.integer() != 0;
    fs.has_speed_bias = in.integer() != 0;
    fs.speed_bias_linearized = in.integer() != 0;
    fs.T_w_i = in.pose();
    fs.T_w_i_lin = in.pose();
    fs.speed_bias = in.fixed<9, 1>();
    fs.speed_bias_lin = in.fixed<9, 1>();
  }
  in.expect("landmarks");
  w.landmarks.resize(in.count());
  for (auto& lm : w.landmarks) {
    lm.id = in.integer();
    lm.host = in.integer();
    lm.param = in.fixed<3, 1>();
    lm.obs.resize(in.count(100000));
    for (auto& o : lm.obs) {
      o.frame = in.integer();
      o.uv0 = in.fixed<2, 1>();
      o.has_right = in.integer() != 0;
      o.uv1 = in.fixed<2, 1>();
    }
  }
  in.expect("imu_links");
  w.imu_links.resize(in.count(100000));
  for (auto& l : w.imu_links) {
    l.from = in.integer();
    l.to = in.integer();
    l.bias_gyro_lin = in.fixed<3, 1>();
    l.bias_accel_lin = in.fixed<3, 1>();
  }
}

void readPrior(Reader& in, WindowSnapshot& w) {
  in.expect("prior");
  const std::string storage = in.word();
  if (storage != "sqrt" && storage != "hessian") in.fail("prior storage must be sqrt or hessian");
  w.prior_representation = storage == "sqrt" ? Representation::kSqrt : Representation::kHessian;
  w.prior_blocks.resize(in.count(100000));
  for (auto& b : w.prior_blocks) {
    b.var.frame_id = in.integer();
    const int64_t block = in.integer();
    if (block != 0 && block != 1) in.fail("prior block kind must be 0 or 1");
    b.var.block = static_cast<StateBlock>(block);
    b.offset = static_cast<int>(in.integer());
    b.T0 = in.pose();
    b.sb0 = in.fixed<9, 1>();
  }
  w.prior_J = in.matrix();
  w.prior_r = in.vector();
  w.prior_H = in.matrix();
  w.prior_b = in.vector();
  w.prior_c = in.number();
}

void readAfter(Reader& in, WindowSnapshot& w) {
  in.expect("after");
  w.after.present = in.integer() != 0;
  if (w.after.present) {
    w.after.lm_iterations = static_cast<int>(in.integer());
    w.after.cost_initial = in.number();
    w.after.cost_final = in.number();
    in.expect("frames");
    w.after.frames.resize(in.count(100000));
    for (auto& fs : w.after.frames) {
      fs.id = in.integer();
      fs.T_w_i = in.pose();
      fs.speed_bias = in.fixed<9, 1>();
    }
    in.expect("landmarks");
    w.after.landmarks.resize(in.count());
    for (auto& lm : w.after.landmarks) {
      lm.id = in.integer();
      lm.param = in.fixed<3, 1>();
    }
  }
  in.expect("end");
}

// The file's text (gzip or plain).
std::string readText(const std::string& path) {
  gzFile f = gzopen(path.c_str(), "rb");  // reads plain text transparently
  if (f == nullptr) throw InputError(path, 0, "cannot open the window file");
  std::string text;
  char buf[1 << 16];
  int n = 0;
  while ((n = gzread(f, buf, sizeof(buf))) > 0) text.append(buf, static_cast<size_t>(n));
  const bool read_error = n < 0;
  gzclose(f);
  if (read_error) throw InputError(path, 0, "cannot read the window file (corrupt gzip?)");
  return text;
}

}  // namespace

void writeWindow(const WindowSnapshot& w, const std::string& path) {
  Writer out;
  writeHeader(out, w);
  writeImu(out, w);
  writeStates(out, w);
  writePrior(out, w);
  writeAfter(out, w);
  writeText(out.text(), path);
}

WindowSnapshot readWindow(const std::string& path) {
  Reader in(readText(path), path);
  WindowSnapshot w;
  readHeader(in, path, w);
  readImu(in, w);
  readStates(in, w);
  readPrior(in, w);
  readAfter(in, w);
  return w;
}

}  // namespace marglab
