#include "core/io/hdf5.h"

#include <algorithm>
#include <cstring>
#include <filesystem>

#include "core/common/error.h"

namespace marglab::h5 {

namespace detail {
void silenceErrors() {
  thread_local const bool silenced = [] {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    return true;
  }();
  (void)silenced;
}
}  // namespace detail

namespace {

// Memory (native) and file (little-endian) HDF5 types of a C++ element type.
template <typename T>
struct Types;
template <>
struct Types<double> {
  static hid_t mem() { return H5T_NATIVE_DOUBLE; }
  static hid_t file() { return H5T_IEEE_F64LE; }
};
template <>
struct Types<float> {
  static hid_t mem() { return H5T_NATIVE_FLOAT; }
  static hid_t file() { return H5T_IEEE_F32LE; }
};
template <>
struct Types<std::int64_t> {
  static hid_t mem() { return H5T_NATIVE_INT64; }
  static hid_t file() { return H5T_STD_I64LE; }
};
template <>
struct Types<std::int32_t> {
  static hid_t mem() { return H5T_NATIVE_INT32; }
  static hid_t file() { return H5T_STD_I32LE; }
};
template <>
struct Types<std::uint8_t> {
  static hid_t mem() { return H5T_NATIVE_UINT8; }
  static hid_t file() { return H5T_STD_U8LE; }
};

// The most specific message on this thread's HDF5 error stack. Must be called before any other
// HDF5 API call, which would clear the stack.
std::string errorDetail() {
  std::string detail;
  auto walk = [](unsigned n, const H5E_error2_t* e, void* out) -> herr_t {
    if (n == 0 && e->desc != nullptr) *static_cast<std::string*>(out) = e->desc;
    return 0;
  };
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, walk, &detail);
  return detail;
}

template <typename GetName>
std::string getString(GetName get) {
  const ssize_t n = get(nullptr, 0);
  if (n < 0) return {};
  std::string s(static_cast<std::size_t>(n) + 1, '\0');
  get(s.data(), s.size());
  s.resize(static_cast<std::size_t>(n));
  return s;
}

std::string fileNameOf(hid_t id) {
  const std::string name = getString([id](char* s, size_t n) { return H5Fget_name(id, s, n); });
  return name.empty() ? "<closed HDF5 file>" : name;
}

std::string objectNameOf(hid_t id) {
  return getString([id](char* s, size_t n) { return H5Iget_name(id, s, n); });
}

std::string join(const std::string& base, const std::string& name) {
  if (name.empty()) return base;
  if (name.front() == '/' || base.empty()) return name;
  return base.back() == '/' ? base + name : base + "/" + name;
}

// Throws InputError naming the file of loc and the object loc/name.
[[noreturn]] void fail(hid_t loc, const std::string& name, const std::string& what) {
  const std::string detail = errorDetail();
  std::string message = join(objectNameOf(loc), name) + ": " + what;
  if (!detail.empty()) message += " (HDF5: " + detail + ")";
  throw InputError(fileNameOf(loc), 0, message);
}

template <typename R>
R check(R result, hid_t loc, const std::string& name, const char* what) {
  if (result < 0) fail(loc, name, what);
  return result;
}

TypeId utf8StringType(H5T_cset_t cset = H5T_CSET_UTF8) {
  TypeId type(H5Tcopy(H5T_C_S1));
  H5Tset_size(type.get(), H5T_VARIABLE);
  H5Tset_cset(type.get(), cset);
  return type;
}

SpaceId simpleSpace(const std::vector<hsize_t>& dims, const std::vector<hsize_t>& max_dims = {}) {
  return SpaceId(H5Screate_simple(static_cast<int>(dims.size()), dims.data(),
                                  max_dims.empty() ? nullptr : max_dims.data()));
}

// Object creation properties of kind (H5P_FILE_CREATE, H5P_GROUP_CREATE, H5P_DATASET_CREATE)
// without modification times in the object headers: the same content gives the same bytes, so
// that a file can be compared with cmp and the fuzzers' seeds made from it are the same each run.
PropId untimedCreation(hid_t kind) {
  PropId plist(H5Pcreate(kind));
  H5Pset_obj_track_times(plist.get(), false);
  return plist;
}

std::string attrLabel(const std::string& name) { return "attribute '" + name + "'"; }

// Writes n elements of an attribute, replacing an existing one; scalar dataspace if scalar.
void writeAttribute(hid_t loc, const std::string& name, hid_t file_type, hid_t mem_type,
                    const void* data, hsize_t n, bool scalar) {
  detail::silenceErrors();
  const std::string label = attrLabel(name);
  if (check(H5Aexists(loc, name.c_str()), loc, "", "cannot query attributes") > 0) {
    check(H5Adelete(loc, name.c_str()), loc, "", ("cannot replace " + label).c_str());
  }
  SpaceId space(scalar   ? H5Screate(H5S_SCALAR)
                : n == 0 ? H5Screate(H5S_NULL)
                         : H5Screate_simple(1, &n, nullptr));
  check(space.get(), loc, "", "cannot create dataspace");
  AttrId attr(check(H5Acreate2(loc, name.c_str(), file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT),
                    loc, "", ("cannot create " + label).c_str()));
  if (n > 0)
    check(H5Awrite(attr.get(), mem_type, data), loc, "", ("cannot write " + label).c_str());
}

// Opens attribute name of loc, returning it with its file type and element count.
struct OpenAttribute {
  AttrId attr;
  TypeId type;
  hsize_t n = 0;
};
OpenAttribute openAttribute(hid_t loc, const std::string& name, bool scalar) {
  detail::silenceErrors();
  const std::string label = attrLabel(name);
  if (check(H5Aexists(loc, name.c_str()), loc, "", "cannot query attributes") <= 0) {
    fail(loc, "", "no " + label);
  }
  OpenAttribute a;
  a.attr = AttrId(
      check(H5Aopen(loc, name.c_str(), H5P_DEFAULT), loc, "", ("cannot open " + label).c_str()));
  a.type = TypeId(check(H5Aget_type(a.attr.get()), loc, "", "cannot get attribute type"));
  SpaceId space(check(H5Aget_space(a.attr.get()), loc, "", "cannot get attribute dataspace"));
  a.n = static_cast<hsize_t>(
      check(H5Sget_simple_extent_npoints(space.get()), loc, "", "cannot get attribute size"));
  if (scalar && a.n != 1) {
    fail(loc, "", label + " has " + std::to_string(a.n) + " elements, expected one");
  }
  return a;
}

template <typename T>
std::vector<T> readNumericAttribute(hid_t loc, const std::string& name, bool scalar,
                                    bool allow_float) {
  OpenAttribute a = openAttribute(loc, name, scalar);
  const H5T_class_t cls = H5Tget_class(a.type.get());
  if (cls != H5T_INTEGER && !(allow_float && cls == H5T_FLOAT)) {
    fail(loc, "", attrLabel(name) + " is not " + (allow_float ? "numeric" : "an integer"));
  }
  std::vector<T> values(a.n);
  if (a.n > 0) {
    check(H5Aread(a.attr.get(), Types<T>::mem(), values.data()), loc, "",
          ("cannot read " + attrLabel(name)).c_str());
  }
  return values;
}

}  // namespace

// ---- Object -------------------------------------------------------------------------------------

std::string Object::path() const { return objectNameOf(id()); }
std::string Object::fileName() const { return fileNameOf(id()); }

bool Object::hasAttr(const std::string& name) const {
  detail::silenceErrors();
  return check(H5Aexists(id(), name.c_str()), id(), "", "cannot query attributes") > 0;
}

std::vector<std::string> Object::attrNames() const {
  detail::silenceErrors();
  std::vector<std::string> names;
  auto collect = [](hid_t, const char* name, const H5A_info_t*, void* out) -> herr_t {
    static_cast<std::vector<std::string>*>(out)->emplace_back(name);
    return 0;
  };
  check(H5Aiterate2(id(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect, &names), id(), "",
        "cannot list attributes");
  return names;
}

void Object::writeDoubles(const std::string& name, const std::vector<double>& v,
                          bool scalar) const {
  writeAttribute(id(), name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, v.data(), v.size(), scalar);
}

void Object::writeInts(const std::string& name, const std::vector<std::int64_t>& v, bool scalar,
                       bool as_int8) const {
  if (as_int8) {
    const std::vector<std::int8_t> b(v.begin(), v.end());
    writeAttribute(id(), name, H5T_STD_I8LE, H5T_NATIVE_INT8, b.data(), b.size(), scalar);
  } else {
    writeAttribute(id(), name, H5T_STD_I64LE, H5T_NATIVE_INT64, v.data(), v.size(), scalar);
  }
}

void Object::writeStrings(const std::string& name, const std::vector<std::string>& v,
                          bool scalar) const {
  std::vector<const char*> ptrs;
  for (const std::string& s : v) ptrs.push_back(s.c_str());
  const TypeId type = utf8StringType();
  writeAttribute(id(), name, type.get(), type.get(), ptrs.data(), ptrs.size(), scalar);
}

std::vector<double> Object::readDoubles(const std::string& name, bool scalar) const {
  return readNumericAttribute<double>(id(), name, scalar, true);
}

std::vector<std::int64_t> Object::readInts(const std::string& name, bool scalar) const {
  return readNumericAttribute<std::int64_t>(id(), name, scalar, false);
}

// Variable-length strings (what we write) and fixed-length ones (h5py's np.bytes_ attributes).
std::vector<std::string> Object::readStrings(const std::string& name, bool scalar) const {
  OpenAttribute a = openAttribute(id(), name, scalar);
  const hid_t file_type = a.type.get();
  if (H5Tget_class(file_type) != H5T_STRING) fail(id(), "", attrLabel(name) + " is not a string");
  const std::string what = "cannot read " + attrLabel(name);
  std::vector<std::string> out;
  if (a.n == 0) return out;
  if (H5Tis_variable_str(file_type) > 0) {
    const TypeId mem = utf8StringType(H5Tget_cset(file_type));
    std::vector<char*> ptrs(a.n, nullptr);
    check(H5Aread(a.attr.get(), mem.get(), ptrs.data()), id(), "", what.c_str());
    for (char* p : ptrs) {
      out.emplace_back(p != nullptr ? p : "");
      H5free_memory(p);
    }
  } else {
    const std::size_t len = H5Tget_size(file_type);
    std::vector<char> buffer(a.n * len);
    check(H5Aread(a.attr.get(), file_type, buffer.data()), id(), "", what.c_str());
    const bool space_padded = H5Tget_strpad(file_type) == H5T_STR_SPACEPAD;
    for (hsize_t i = 0; i < a.n; ++i) {
      std::string s(buffer.data() + i * len, len);
      s.resize(std::strlen(s.c_str()));
      if (space_padded) s.erase(s.find_last_not_of(' ') + 1);
      out.push_back(std::move(s));
    }
  }
  return out;
}

// ---- Dataset ------------------------------------------------------------------------------------

std::vector<hsize_t> Dataset::shape() const {
  detail::silenceErrors();
  SpaceId space(check(H5Dget_space(id()), id(), "", "cannot get dataspace"));
  const int rank = check(H5Sget_simple_extent_ndims(space.get()), id(), "", "cannot get rank");
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
  H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
  return dims;
}

namespace {

// A corrupted file can claim more than it holds, and the read sizes its buffers from the claim
// (fuzz_track_hdf5: 14.7 GB from a dataspace, 990 MB from a chunk's size in a 42 KB file): the
// bytes stored for the dataset must fit in the file, and the elements' raw bytes in those —
// times deflate's largest ratio, 1032:1, when filtered. Returns the number of elements.
hsize_t storedElements(hid_t dataset, const std::vector<hsize_t>& dims) {
  const TypeId type(check(H5Dget_type(dataset), dataset, "", "cannot get datatype"));
  const PropId dcpl(check(H5Dget_create_plist(dataset), dataset, "", "cannot get properties"));
  const FileId file(check(H5Iget_file_id(dataset), dataset, "", "cannot get its file"));
  hsize_t file_bytes = 0;
  check(H5Fget_filesize(file.get(), &file_bytes), dataset, "", "cannot get the file's size");
  const hsize_t stored = H5Dget_storage_size(dataset);
  if (stored > file_bytes) {
    fail(dataset, "",
         "the file claims " + std::to_string(stored) + " bytes for it, more than its own " +
             std::to_string(file_bytes) + " (corrupted file)");
  }
  constexpr hsize_t kDeflateMaxRatio = 1032;
  const hsize_t capacity = H5Pget_nfilters(dcpl.get()) > 0 ? stored * kDeflateMaxRatio : stored;
  const hsize_t max_elements = capacity / std::max<std::size_t>(H5Tget_size(type.get()), 1);
  hsize_t n = 1;
  for (const hsize_t d : dims) {
    if (d != 0 && n > max_elements / d) {
      fail(dataset, "",
           "its shape claims more elements than the " + std::to_string(stored) +
               " bytes the file stores for it can hold (corrupted file)");
    }
    n *= d;
  }
  return n;
}

}  // namespace

template <typename T>
std::vector<T> Dataset::read() const {
  const std::vector<hsize_t> dims = shape();
  std::vector<T> values(storedElements(id(), dims));
  if (!values.empty()) {
    check(H5Dread(id(), Types<T>::mem(), H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), id(), "",
          "cannot read dataset");
  }
  return values;
}

template <typename T>
RowMatrix<T> Dataset::readMatrix() const {
  const std::vector<hsize_t> dims = shape();
  if (dims.size() != 1 && dims.size() != 2) {
    fail(id(), "", "rank " + std::to_string(dims.size()) + ", expected a 1-D or 2-D dataset");
  }
  const std::vector<T> values = read<T>();
  const auto cols = static_cast<Eigen::Index>(dims.size() == 2 ? dims[1] : 1);
  return Eigen::Map<const RowMatrix<T>>(values.data(), static_cast<Eigen::Index>(dims[0]), cols);
}

template <typename T>
std::vector<T> Dataset::readRows(hsize_t first, hsize_t count) const {
  const std::vector<hsize_t> dims = shape();
  if (dims.size() != 1 && dims.size() != 2) {
    fail(id(), "", "rank " + std::to_string(dims.size()) + ", expected a 1-D or 2-D dataset");
  }
  storedElements(id(), dims);
  if (first + count > dims[0]) {
    fail(id(), "",
         "rows [" + std::to_string(first) + ", " + std::to_string(first + count) +
             ") out of range, the dataset has " + std::to_string(dims[0]));
  }
  const hsize_t row_length = dims.size() == 2 ? dims[1] : 1;
  std::vector<T> values(count * row_length);
  if (values.empty()) return values;
  SpaceId file_space(check(H5Dget_space(id()), id(), "", "cannot get dataspace"));
  const hsize_t start[2] = {first, 0};
  const hsize_t block[2] = {count, row_length};
  check(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, block, nullptr), id(),
        "", "cannot select rows");
  const SpaceId mem_space = simpleSpace({count * row_length});
  check(
      H5Dread(id(), Types<T>::mem(), mem_space.get(), file_space.get(), H5P_DEFAULT, values.data()),
      id(), "", "cannot read rows");
  return values;
}

// ---- Group --------------------------------------------------------------------------------------

bool Group::exists(const std::string& path) const {
  detail::silenceErrors();
  std::size_t pos = path.find_first_not_of('/');
  while (pos != std::string::npos) {
    const std::size_t end = path.find('/', pos);
    const std::string prefix = path.substr(0, end);
    if (check(H5Lexists(id(), prefix.c_str(), H5P_DEFAULT), id(), prefix, "cannot query link") <=
        0) {
      return false;
    }
    pos = end == std::string::npos ? end : path.find_first_not_of('/', end);
  }
  return true;
}

Group Group::openGroup(const std::string& path) const {
  if (!exists(path)) fail(id(), path, "no such group");
  return Group(check(H5Gopen2(id(), path.c_str(), H5P_DEFAULT), id(), path, "not a group"));
}

// Each missing group along the path is created here rather than by HDF5's intermediate-group
// option, which would create them with the default (timed) properties.
Group Group::group(const std::string& path) const {
  if (exists(path)) return openGroup(path);
  const PropId gcpl = untimedCreation(H5P_GROUP_CREATE);
  std::size_t pos = path.find_first_not_of('/');
  while (pos != std::string::npos) {
    const std::size_t end = path.find('/', pos);
    const std::string prefix = path.substr(0, end);
    if (!exists(prefix)) {
      ObjectId created(check(H5Gcreate2(id(), prefix.c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT),
                             id(), prefix, "cannot create group"));
    }
    pos = end == std::string::npos ? end : path.find_first_not_of('/', end);
  }
  return openGroup(path);
}

Dataset Group::openDataset(const std::string& path) const {
  if (!exists(path)) fail(id(), path, "no such dataset");
  return Dataset(check(H5Dopen2(id(), path.c_str(), H5P_DEFAULT), id(), path, "not a dataset"));
}

std::vector<std::string> Group::members() const {
  detail::silenceErrors();
  H5G_info_t info;
  check(H5Gget_info(id(), &info), id(), "", "cannot get group info");
  std::vector<std::string> names;
  for (hsize_t i = 0; i < info.nlinks; ++i) {
    names.push_back(getString([this, i](char* s, size_t n) {
      return H5Lget_name_by_idx(id(), ".", H5_INDEX_NAME, H5_ITER_INC, i, s, n, H5P_DEFAULT);
    }));
  }
  return names;
}

Dataset Group::createDataset(const std::string& name, hid_t file_type,
                             const std::vector<hsize_t>& dims, hsize_t chunk_rows,
                             int deflate) const {
  if (exists(name)) fail(id(), name, "already exists");
  std::vector<hsize_t> max_dims = dims;
  std::vector<hsize_t> chunk = dims;
  const PropId dcpl = untimedCreation(H5P_DATASET_CREATE);
  if (chunk_rows > 0) {
    max_dims.front() = H5S_UNLIMITED;
    chunk.front() = chunk_rows;
    check(H5Pset_chunk(dcpl.get(), static_cast<int>(chunk.size()), chunk.data()), id(), name,
          "invalid chunk shape");
    if (deflate > 0) {
      check(H5Pset_shuffle(dcpl.get()), id(), name, "cannot enable shuffle");
      check(H5Pset_deflate(dcpl.get(), static_cast<unsigned>(deflate)), id(), name,
            "invalid deflate level");
    }
  }
  const SpaceId space = simpleSpace(dims, max_dims);
  check(space.get(), id(), name, "invalid dataspace");
  const std::size_t slash = name.find_last_of('/');
  if (slash != std::string::npos && slash > 0) group(name.substr(0, slash));
  return Dataset(check(
      H5Dcreate2(id(), name.c_str(), file_type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
      id(), name, "cannot create dataset"));
}

template <typename T>
Dataset Group::write(const std::string& name, const T* row_major, std::size_t rows,
                     std::size_t cols) const {
  Dataset dataset = createDataset(name, Types<T>::file(), {rows, cols}, 0, 0);
  if (rows * cols > 0) {
    check(H5Dwrite(dataset.id(), Types<T>::mem(), H5S_ALL, H5S_ALL, H5P_DEFAULT, row_major), id(),
          name, "cannot write dataset");
  }
  return dataset;
}

template <typename T>
Dataset Group::write(const std::string& name, const std::vector<T>& values) const {
  Dataset dataset = createDataset(name, Types<T>::file(), {values.size()}, 0, 0);
  if (!values.empty()) {
    check(H5Dwrite(dataset.id(), Types<T>::mem(), H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()),
          id(), name, "cannot write dataset");
  }
  return dataset;
}

// ---- File ---------------------------------------------------------------------------------------

File File::create(const std::string& path) {
  detail::silenceErrors();
  File f;
  f.path_ = path;
  // The temporary now, so that an unwritable folder fails before the work, not after it.
  f.out_ = std::make_unique<AtomicFile>(path);
  // In memory (core driver, no backing store): HDF5 never writes to the disk itself, so a full
  // disk fails in AtomicFile with errno, never inside H5Fclose (which leaves HDF5 1.10's state
  // broken and crashed at exit).
  const PropId fapl(H5Pcreate(H5P_FILE_ACCESS));
  H5Pset_fclose_degree(fapl.get(), H5F_CLOSE_STRONG);
  constexpr std::size_t kIncrement = 1 << 20;
  H5Pset_fapl_core(fapl.get(), kIncrement, false);
  const PropId fcpl = untimedCreation(H5P_FILE_CREATE);
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl.get(), fapl.get());
  if (file < 0) throw InputError(path, 0, "cannot create (HDF5: " + errorDetail() + ")");
  f.file_ = FileId(file);
  f.id_ = ObjectId(check(H5Gopen2(file, "/", H5P_DEFAULT), file, "/", "cannot open root group"));
  return f;
}

File File::openReadOnly(const std::string& path) {
  detail::silenceErrors();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(path, 0, "no such file");
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file < 0) {
    throw InputError(path, 0, "not an HDF5 file or unreadable (HDF5: " + errorDetail() + ")");
  }
  File f;
  f.path_ = path;
  f.file_ = FileId(file);
  f.id_ = ObjectId(check(H5Gopen2(file, "/", H5P_DEFAULT), file, "/", "cannot open root group"));
  return f;
}

File::~File() { discard(); }

File::File(File&& other) noexcept
    : Group(std::move(other)),
      file_(std::move(other.file_)),
      path_(std::move(other.path_)),
      out_(std::move(other.out_)) {}

File& File::operator=(File&& other) noexcept {
  if (this != &other) {
    discard();
    Group::operator=(std::move(other));
    file_ = std::move(other.file_);
    path_ = std::move(other.path_);
    out_ = std::move(other.out_);
  }
  return *this;
}

void File::discard() noexcept {
  id_.reset();
  file_.reset();
  out_.reset();
}

void File::commit() {
  if (!out_) throw InputError(path_, 0, "commit: the file is not being written");
  detail::silenceErrors();
  id_.reset();
  const hid_t file = file_.get();
  const ssize_t size =
      H5Fflush(file, H5F_SCOPE_GLOBAL) < 0 ? -1 : H5Fget_file_image(file, nullptr, 0);
  std::vector<char> image(size > 0 ? static_cast<std::size_t>(size) : 0);
  if (size < 0 || H5Fget_file_image(file, image.data(), image.size()) != size ||
      H5Fclose(file_.release()) < 0) {
    const std::string detail = errorDetail();
    discard();
    throw InputError(path_, 0, "cannot build the file image (HDF5: " + detail + ")");
  }
  out_->write(image.data(), image.size());
  out_->commit();
  out_.reset();
}

// ---- Appendable, ragged arrays ------------------------------------------------------------------

template <typename T>
Appendable<T>::Appendable(const Group& parent, const std::string& name, std::size_t cols,
                          hsize_t chunk_rows, int deflate)
    : cols_(cols) {
  std::vector<hsize_t> dims{0};
  if (cols > 0) dims.push_back(cols);
  dataset_ = parent.createDataset(name, Types<T>::file(), dims, chunk_rows, deflate);
}

template <typename T>
void Appendable<T>::append(const T* values, std::size_t n) {
  if (n == 0) return;
  const hid_t ds = dataset_.id();
  const hsize_t k = rowLength();
  if (n % k != 0) {
    fail(ds, "",
         "append of " + std::to_string(n) + " values, not whole rows of " + std::to_string(k));
  }
  const int rank = cols_ == 0 ? 1 : 2;
  const hsize_t start[2] = {rows_, 0};
  const hsize_t count[2] = {n / k, k};
  const hsize_t dims[2] = {rows_ + n / k, k};
  check(H5Dset_extent(ds, dims), ds, "", "cannot extend dataset");
  SpaceId file_space(check(H5Dget_space(ds), ds, "", "cannot get dataspace"));
  check(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr), ds,
        "", "cannot select rows");
  const SpaceId mem_space(H5Screate_simple(rank, count, nullptr));
  check(H5Dwrite(ds, Types<T>::mem(), mem_space.get(), file_space.get(), H5P_DEFAULT, values), ds,
        "", "cannot append");
  rows_ += n / k;
}

template <typename T>
RaggedWriter<T>::RaggedWriter(const Group& parent, const std::string& name, hsize_t chunk,
                              int deflate)
    : group_(parent.group(name)),
      values_(group_, "values", 0, chunk, deflate),
      offsets_(group_, "offsets", 0, chunk, deflate) {
  group_.setAttr("layout", "ragged: row i = values[offsets[i]:offsets[i+1]]");
  offsets_.append(std::int64_t{0});
}

template <typename T>
void RaggedWriter<T>::append(const T* row, std::size_t n) {
  values_.append(row, n);
  total_ += static_cast<std::int64_t>(n);
  offsets_.append(total_);
}

template <typename T>
RaggedReader<T>::RaggedReader(const Group& parent, const std::string& name) {
  const Group group = parent.openGroup(name);
  values_ = group.openDataset("values");
  offsets_ = group.readVector<std::int64_t>("offsets");
  const std::vector<hsize_t> dims = values_.shape();
  bool valid = dims.size() == 1 && !offsets_.empty() && offsets_.front() == 0 &&
               offsets_.back() == static_cast<std::int64_t>(dims[0]);
  for (std::size_t i = 1; valid && i < offsets_.size(); ++i) valid = offsets_[i - 1] <= offsets_[i];
  if (!valid) {
    fail(group.id(), "",
         "not a ragged array (need 1-D values[K], offsets[M+1] from 0 to K, "
         "non-decreasing)");
  }
}

template <typename T>
std::vector<T> RaggedReader<T>::row(std::size_t i) const {
  if (i >= rows()) {
    fail(values_.id(), "",
         "row " + std::to_string(i) + " out of range, " + std::to_string(rows()) + " rows");
  }
  const auto first = static_cast<hsize_t>(offsets_[i]);
  return values_.readRows<T>(first, static_cast<hsize_t>(offsets_[i + 1]) - first);
}

#define MARGLAB_H5_INSTANTIATE(T)                                                                 \
  template std::vector<T> Dataset::read<T>() const;                                               \
  template RowMatrix<T> Dataset::readMatrix<T>() const;                                           \
  template std::vector<T> Dataset::readRows<T>(hsize_t, hsize_t) const;                           \
  template Dataset Group::write<T>(const std::string&, const T*, std::size_t, std::size_t) const; \
  template Dataset Group::write<T>(const std::string&, const std::vector<T>&) const;              \
  template class Appendable<T>;                                                                   \
  template class RaggedWriter<T>;                                                                 \
  template class RaggedReader<T>;
MARGLAB_H5_ELEMENT_TYPES(MARGLAB_H5_INSTANTIATE)

}  // namespace marglab::h5
