#pragma once
// HDF5 I/O for results files (docs/design.md §6): a small RAII wrapper over the HDF5 C API.
//
// What maps to which HDF5 construct:
//   h5::File            an HDF5 file; a File is also its root group "/" (attributes on the file are
//                       attributes of "/"). File::create(path) builds the file in memory (HDF5's
//                       core driver) and creates its temporary "<path>.tmp-<pid>-<n>" at once
//                       (AtomicFile, atomic_file.h); commit() writes the image there, fsyncs and
//                       rename(2)s it onto <path>. So <path> is either absent, the previous file,
//                       or the complete new one (a sweep that counts a run as done when <path>
//                       exists never sees a half-written file), and a full disk is a clear
//                       InputError at commit, never a failure inside HDF5. A File destroyed
//                       without commit() (exception, early return, interrupt) deletes its
//                       temporary; only SIGKILL can leave a "*.tmp-*" behind, never <path>.
//                       commit() closes every object of the file (fclose degree
//                       H5F_CLOSE_STRONG): handles taken from it become invalid and any later use
//                       throws. Files are a few MB (docs/design.md §6), so memory is no concern.
//   h5::Group           an HDF5 group; nested paths ("marg/eigenvalues") create intermediates.
//   h5::Dataset         a dataset. Group::write stores a whole 1-D vector or 2-D row-major matrix
//                       (contiguous layout); Dataset::read* convert to the requested element type.
//   h5::Appendable<T>   a chunked dataset of shape (n) or (n, k) with max dims (unlimited) or
//                       (unlimited, k), grown with H5Dset_extent on each append (one row per frame:
//                       t_ns, p_est[., 3], ...). Optional shuffle + deflate (level 1-9; 0 = off).
//   h5::RaggedWriter<T> a group holding values[K] (T) and offsets[M+1] (int64, offsets[0] = 0):
//   h5::RaggedReader<T> row i is values[offsets[i] : offsets[i+1]] (CSR layout; in h5py
//                       g["values"][o[i]:o[i+1]]). The group carries attribute "layout".
//   attributes          std::string / const char*  -> scalar variable-length UTF-8 string
//                                                     (h5py returns str)
//                       bool                       -> int8 0/1
//                       other integers             -> int64
//                       float, double              -> IEEE f64
//                       std::vector<arithmetic>    -> 1-D int64 or f64 (bool: int8)
//                       std::vector<std::string>   -> 1-D variable-length UTF-8 strings
//                       Setting an existing attribute replaces it.
// Dataset element types: double, float, int64_t, int32_t, uint8_t (stored little-endian).
//
// Errors: every failure throws marglab::InputError(file, 0, "<object path>: what (HDF5: detail)"),
// e.g. "run.h5: /frames/p_est: no such dataset". HDF5's automatic error-stack printing is turned
// off (per thread: in the thread-safe library the error stack is per thread).

#include <hdf5.h>

#include <Eigen/Core>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/common/atomic_file.h"

namespace marglab::h5 {

// Dataset element types with explicit instantiations (X is a macro taking the type).
#define MARGLAB_H5_ELEMENT_TYPES(X) \
  X(double) X(float) X(std::int64_t) X(std::int32_t) X(std::uint8_t)

template <typename T>
using RowMatrix = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

namespace detail {
// Switches off HDF5's error printing for the calling thread (idempotent, cheap).
void silenceErrors();
template <typename T>
struct IsVector : std::false_type {};
template <typename U, typename A>
struct IsVector<std::vector<U, A>> : std::true_type {};
template <typename T>
inline constexpr bool kAlwaysFalse = false;
}  // namespace detail

// Owns one HDF5 identifier and closes it with Close. Move-only. Closing an identifier the
// library has already closed (objects of a committed file) is a silent no-op.
template <herr_t (*Close)(hid_t)>
class Id {
 public:
  Id() = default;
  explicit Id(hid_t id) : id_(id) {}
  ~Id() { reset(); }
  Id(Id&& other) noexcept : id_(other.release()) {}
  Id& operator=(Id&& other) noexcept {
    if (this != &other) {
      reset();
      id_ = other.release();
    }
    return *this;
  }
  Id(const Id&) = delete;
  Id& operator=(const Id&) = delete;

  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  hid_t release() { return std::exchange(id_, H5I_INVALID_HID); }
  void reset() {
    if (id_ >= 0) {
      detail::silenceErrors();
      if (H5Iis_valid(id_) > 0) Close(id_);
    }
    id_ = H5I_INVALID_HID;
  }

 private:
  hid_t id_ = H5I_INVALID_HID;
};
using FileId = Id<H5Fclose>;
using GroupId = Id<H5Gclose>;
using DatasetId = Id<H5Dclose>;
using SpaceId = Id<H5Sclose>;
using TypeId = Id<H5Tclose>;
using AttrId = Id<H5Aclose>;
using PropId = Id<H5Pclose>;
using ObjectId = Id<H5Oclose>;

// A group or dataset: the things that carry attributes.
class Object {
 public:
  hid_t id() const { return id_.get(); }
  bool valid() const { return id_.valid(); }
  std::string path() const;      // HDF5 path, e.g. "/frames/t_ns"
  std::string fileName() const;  // the file it lives in (the temporary name while writing)

  bool hasAttr(const std::string& name) const;
  std::vector<std::string> attrNames() const;
  template <typename T>
  void setAttr(const std::string& name, const T& value) const;
  // T: std::string, bool, any integer, float, double, std::vector of those. A scalar T reads a
  // scalar or one-element attribute; integers require an integer attribute, floating point
  // accepts integer or float attributes.
  template <typename T>
  T attr(const std::string& name) const;

 protected:
  Object() = default;
  explicit Object(hid_t owned) : id_(owned) {}
  ObjectId id_;

 private:
  void writeDoubles(const std::string& name, const std::vector<double>& v, bool scalar) const;
  void writeInts(const std::string& name, const std::vector<std::int64_t>& v, bool scalar,
                 bool as_int8) const;
  void writeStrings(const std::string& name, const std::vector<std::string>& v, bool scalar) const;
  std::vector<double> readDoubles(const std::string& name, bool scalar) const;
  std::vector<std::int64_t> readInts(const std::string& name, bool scalar) const;
  std::vector<std::string> readStrings(const std::string& name, bool scalar) const;
};

class Dataset : public Object {
 public:
  Dataset() = default;
  explicit Dataset(hid_t owned) : Object(owned) {}
  std::vector<hsize_t> shape() const;
  // All elements in row-major order.
  template <typename T>
  std::vector<T> read() const;
  // Rank 2 as stored; rank 1 as an n×1 column.
  template <typename T>
  RowMatrix<T> readMatrix() const;
  // Rows [first, first + count) along dimension 0, row-major (rank 1 or 2).
  template <typename T>
  std::vector<T> readRows(hsize_t first, hsize_t count) const;
};

class Group : public Object {
 public:
  Group() = default;
  explicit Group(hid_t owned) : Object(owned) {}

  // Opens the group at path (relative or absolute), creating it and missing parents.
  Group group(const std::string& path) const;
  // Opens an existing group; InputError if it does not exist.
  Group openGroup(const std::string& path) const;
  Dataset openDataset(const std::string& path) const;
  // True if every component of path exists (any object type).
  bool exists(const std::string& path) const;
  // Names of the direct members, in name order.
  std::vector<std::string> members() const;

  // Whole datasets (contiguous). name may contain a path; parents are created. The name must
  // not exist yet.
  template <typename T>
  Dataset write(const std::string& name, const std::vector<T>& values) const;
  template <typename T>
  Dataset write(const std::string& name, const T* row_major, std::size_t rows,
                std::size_t cols) const;
  template <typename Derived>
  Dataset writeMatrix(const std::string& name, const Eigen::MatrixBase<Derived>& m) const {
    const RowMatrix<typename Derived::Scalar> r = m;
    return write(name, r.data(), static_cast<std::size_t>(r.rows()),
                 static_cast<std::size_t>(r.cols()));
  }
  template <typename T>
  std::vector<T> readVector(const std::string& name) const {
    return openDataset(name).read<T>();
  }
  template <typename T>
  RowMatrix<T> readMatrix(const std::string& name) const {
    return openDataset(name).readMatrix<T>();
  }

  // A dataset for the writers below: dims (0) or (0, cols) if chunk_rows > 0 (extendible
  // along dimension 0), else fixed dims.
  Dataset createDataset(const std::string& name, hid_t file_type, const std::vector<hsize_t>& dims,
                        hsize_t chunk_rows, int deflate) const;
};

class File : public Group {
 public:
  File() = default;
  // Writes to a temporary sibling of path; nothing appears at path before commit().
  static File create(const std::string& path);
  // Objects taken from a read-only File keep the file open after the File is destroyed. libhdf5
  // trusts the file: one a user hands in is read through hdf5_trust.h first.
  static File openReadOnly(const std::string& path);
  ~File();
  File(File&& other) noexcept;
  File& operator=(File&& other) noexcept;

  // Flush, close and atomically rename the temporary onto path (replacing an existing file).
  void commit();
  const std::string& path() const { return path_; }

 private:
  void discard() noexcept;
  FileId file_;
  std::string path_;
  std::unique_ptr<AtomicFile> out_;  // the temporary, until commit()
};

// An extendible chunked dataset: 1-D (cols == 0) or n×cols. append() writes through at once.
template <typename T>
class Appendable {
 public:
  Appendable() = default;
  Appendable(const Group& parent, const std::string& name, std::size_t cols, hsize_t chunk_rows,
             int deflate);

  // n values in row-major order: n / rowLength() rows; n must be a multiple of rowLength().
  void append(const T* values, std::size_t n);
  void append(T value) { append(&value, 1); }
  void append(const std::vector<T>& values) { append(values.data(), values.size()); }
  void append(std::initializer_list<T> values) { append(values.begin(), values.size()); }
  // A vector (its coefficients in order) or a matrix of rows; converted to T.
  template <typename Derived>
  void append(const Eigen::MatrixBase<Derived>& m) {
    const RowMatrix<T> r = m.template cast<T>();
    append(r.data(), static_cast<std::size_t>(r.size()));
  }

  hsize_t rows() const { return rows_; }
  std::size_t rowLength() const { return cols_ == 0 ? 1 : cols_; }
  const Dataset& dataset() const { return dataset_; }

 private:
  Dataset dataset_;
  std::size_t cols_ = 0;
  hsize_t rows_ = 0;
};

// 1-D: shape (n,), e.g. /frames/t_ns.
template <typename T>
Appendable<T> appendable(const Group& parent, const std::string& name, hsize_t chunk_rows = 1024,
                         int deflate = 0) {
  return Appendable<T>(parent, name, 0, chunk_rows, deflate);
}
// n×cols, e.g. /frames/p_est with cols = 3.
template <typename T>
Appendable<T> appendableRows(const Group& parent, const std::string& name, std::size_t cols,
                             hsize_t chunk_rows = 1024, int deflate = 0) {
  return Appendable<T>(parent, name, cols, chunk_rows, deflate);
}

// Ragged rows group parent/name = {values, offsets}; appends one row at a time.
template <typename T>
class RaggedWriter {
 public:
  RaggedWriter() = default;
  RaggedWriter(const Group& parent, const std::string& name, hsize_t chunk = 4096, int deflate = 0);
  void append(const T* row, std::size_t n);
  void append(const std::vector<T>& row) { append(row.data(), row.size()); }
  template <typename Derived>
  void append(const Eigen::MatrixBase<Derived>& row) {
    const RowMatrix<T> r = row.template cast<T>();
    append(r.data(), static_cast<std::size_t>(r.size()));
  }
  hsize_t rows() const { return offsets_.rows() == 0 ? 0 : offsets_.rows() - 1; }
  const Group& group() const { return group_; }

 private:
  Group group_;
  Appendable<T> values_;
  Appendable<std::int64_t> offsets_;
  std::int64_t total_ = 0;
};

// Reads the offsets at construction (validating the layout); row(i) reads one row's values.
template <typename T>
class RaggedReader {
 public:
  RaggedReader(const Group& parent, const std::string& name);
  std::size_t rows() const { return offsets_.size() - 1; }
  std::vector<T> row(std::size_t i) const;
  const std::vector<std::int64_t>& offsets() const { return offsets_; }

 private:
  Dataset values_;
  std::vector<std::int64_t> offsets_;
};

template <typename T>
void Object::setAttr(const std::string& name, const T& value) const {
  if constexpr (std::is_same_v<T, bool>) {
    writeInts(name, {value ? 1 : 0}, true, true);
  } else if constexpr (std::is_integral_v<T>) {
    writeInts(name, {static_cast<std::int64_t>(value)}, true, false);
  } else if constexpr (std::is_floating_point_v<T>) {
    writeDoubles(name, {static_cast<double>(value)}, true);
  } else if constexpr (std::is_convertible_v<const T&, std::string>) {
    writeStrings(name, {std::string(value)}, true);
  } else if constexpr (detail::IsVector<T>::value) {
    using U = typename T::value_type;
    if constexpr (std::is_same_v<U, std::string>) {
      writeStrings(name, value, false);
    } else if constexpr (std::is_integral_v<U>) {
      writeInts(name, std::vector<std::int64_t>(value.begin(), value.end()), false,
                std::is_same_v<U, bool>);
    } else {
      static_assert(std::is_floating_point_v<U>, "attribute vectors hold numbers or strings");
      writeDoubles(name, std::vector<double>(value.begin(), value.end()), false);
    }
  } else {
    static_assert(detail::kAlwaysFalse<T>, "unsupported attribute type");
  }
}

template <typename T>
T Object::attr(const std::string& name) const {
  if constexpr (std::is_same_v<T, std::string>) {
    return readStrings(name, true).front();
  } else if constexpr (std::is_same_v<T, bool>) {
    return readInts(name, true).front() != 0;
  } else if constexpr (std::is_integral_v<T>) {
    return static_cast<T>(readInts(name, true).front());
  } else if constexpr (std::is_floating_point_v<T>) {
    return static_cast<T>(readDoubles(name, true).front());
  } else if constexpr (detail::IsVector<T>::value) {
    using U = typename T::value_type;
    if constexpr (std::is_same_v<U, std::string>) {
      return readStrings(name, false);
    } else if constexpr (std::is_integral_v<U>) {
      const auto v = readInts(name, false);
      return T(v.begin(), v.end());
    } else {
      const auto v = readDoubles(name, false);
      return T(v.begin(), v.end());
    }
  } else {
    static_assert(detail::kAlwaysFalse<T>, "unsupported attribute type");
  }
}

}  // namespace marglab::h5
