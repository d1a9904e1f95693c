// libFuzzer harness: marglab's checks of a decoded HDF5 track file (core/sim/track_io.h,
// tracksFromContent) — what CI fuzzes of the HDF5 track reader. libhdf5's decoding is not fuzzed
// here: the trust boundary (core/io/hdf5_trust.h) contains what libhdf5 does not survive, and a
// campaign through it is fuzz_track_hdf5 (fuzz/README.md).
//
// The input is the content in a small binary form, little-endian, each field read while bytes
// remain (then "" or 0): format (u8 length, bytes), format_version (i32), sequence (u8 length,
// bytes), seed (u64); the columns t_ns, offsets, track_id, landmark_id (i64), u0, v0, u1, v1
// (f64), has_right, is_outlier (u8), each a u32 count and that many values (the count cut to the
// bytes left); landmarks_w: u8 present, u32 rows, u8 columns, the values row by row.
// fuzz/make_seeds.py writes the committed track files in this form.

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "core/sim/track_io.h"
#include "fuzz/fuzz_input.h"

using namespace marglab;

namespace {

class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : p_(data), left_(size) {}
  template <typename T>
  T take() {
    T value{};
    const std::size_t n = std::min(sizeof(T), left_);
    std::memcpy(&value, p_, n);
    p_ += n;
    left_ -= n;
    return value;
  }
  std::string text() {
    const std::size_t n = std::min<std::size_t>(take<std::uint8_t>(), left_);
    std::string s(reinterpret_cast<const char*>(p_), n);
    p_ += n;
    left_ -= n;
    return s;
  }
  template <typename T>
  std::vector<T> column(std::size_t count) {
    std::vector<T> v(std::min<std::size_t>(count, left_ / sizeof(T)));
    for (T& x : v) x = take<T>();
    return v;
  }
  template <typename T>
  std::vector<T> column() {
    return column<T>(take<std::uint32_t>());
  }

 private:
  const std::uint8_t* p_;
  std::size_t left_;
};

TrackFileContent decode(Bytes& in) {
  TrackFileContent c;
  c.format = in.text();
  c.format_version = in.take<std::int32_t>();
  c.sequence = in.text();
  c.seed = in.take<std::uint64_t>();
  for (auto* column : {&c.t_ns, &c.offsets, &c.track_id, &c.landmark_id}) {
    *column = in.column<std::int64_t>();
  }
  for (auto* column : {&c.u0, &c.v0, &c.u1, &c.v1}) *column = in.column<double>();
  for (auto* column : {&c.has_right, &c.is_outlier}) *column = in.column<std::uint8_t>();
  if (in.take<std::uint8_t>() != 0) {
    const std::size_t rows = in.take<std::uint32_t>();
    const std::size_t cols = in.take<std::uint8_t>();
    std::vector<double> values = in.column<double>(rows * cols);
    const std::size_t kept_rows = cols == 0 ? rows : values.size() / cols;
    c.landmarks_w.emplace(kept_rows, cols);
    for (std::size_t i = 0; i < kept_rows * cols; ++i) c.landmarks_w->data()[i] = values[i];
  }
  return c;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Bytes in(data, size);
  const TrackFileContent content = decode(in);
  fuzz::expectInputErrorOrSuccess([&] { tracksFromContent("input.tracks.h5", content); });
  return 0;
}
