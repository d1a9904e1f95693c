#include "core/io/hdf5_vlen_check.h"

#include <sys/stat.h>

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <tuple>
#include <vector>

namespace marglab::h5::detail {

namespace {

// The first descriptor of `n` (each `size` bytes, `stride` apart) that is not a string of
// `heaps`, with why; nullopt when all are. A null string (address 0) is not read by libhdf5.
std::optional<std::string> refuseDescriptor(const unsigned char* buf, std::size_t n,
                                            std::size_t size, std::size_t stride,
                                            const GlobalHeapObjects& heaps) {
  const std::size_t offsets = size - 8;  // length (4), address, index (4)
  if (offsets != 2 && offsets != 4 && offsets != 8) {
    return "a string descriptor of " + std::to_string(size) + " bytes (expected 10, 12 or 16)";
  }
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char* d = buf + i * stride;
    const std::uint64_t length = littleEndian(d, 4);
    const std::uint64_t address = littleEndian(d + 4, offsets);
    const std::uint64_t index = littleEndian(d + 4 + offsets, 4);
    if (address == 0) continue;
    const std::string object = "global heap object (collection at address " +
                               std::to_string(address) + ", index " + std::to_string(index) + ")";
    const auto it = heaps.size.find({address, index});
    if (it == heaps.size.end()) {
      return "string " + std::to_string(i) + " names a " + object + " the file does not hold";
    }
    if (it->second != length) {
      return "string " + std::to_string(i) + " claims " + std::to_string(length) + " bytes; its " +
             object + " holds " + std::to_string(it->second);
    }
  }
  return std::nullopt;
}

// What the conversion checks against, set by readVlenStrings for the duration of its H5Aread.
struct ReadContext {
  const GlobalHeapObjects* heaps;
  std::optional<std::string> refusal;
};
thread_local ReadContext* t_read = nullptr;
H5T_conv_t g_libhdf5_conversion = nullptr;

herr_t checkedConversion(hid_t src, hid_t dst, H5T_cdata_t* cdata, std::size_t n,
                         std::size_t buf_stride, std::size_t bkg_stride, void* buf, void* bkg,
                         hid_t dxpl) {
  // Variable-length sequences (the same HDF5 class) stay with libhdf5's conversion alone.
  if (cdata->command == H5T_CONV_INIT &&
      (H5Tis_variable_str(src) <= 0 || H5Tis_variable_str(dst) <= 0)) {
    return -1;
  }
  if (cdata->command == H5T_CONV_CONV && t_read != nullptr) {
    const std::size_t size = H5Tget_size(src);  // the descriptor on disk
    t_read->refusal = refuseDescriptor(static_cast<const unsigned char*>(buf), n, size,
                                       buf_stride == 0 ? size : buf_stride, *t_read->heaps);
    if (t_read->refusal) return -1;
  }
  return g_libhdf5_conversion(src, dst, cdata, n, buf_stride, bkg_stride, buf, bkg, dxpl);
}

// libhdf5's own conversion between variable-length types (one function for sequences and
// strings; found through a path between two sequences, as no two string types are convertible
// without being a no-op), then the checked one registered in front of it for the same class.
void registerCheckedConversion() {
  static std::once_flag once;
  std::call_once(once, [] {
    const hid_t signed_chars = H5Tvlen_create(H5T_NATIVE_SCHAR);
    const hid_t unsigned_chars = H5Tvlen_create(H5T_NATIVE_UCHAR);
    H5T_cdata_t* cdata = nullptr;
    g_libhdf5_conversion = H5Tfind(signed_chars, unsigned_chars, &cdata);
    const herr_t registered =
        g_libhdf5_conversion == nullptr
            ? -1
            : H5Tregister(H5T_PERS_SOFT, "marglab checked vlen string", signed_chars,
                          unsigned_chars, checkedConversion);
    H5Tclose(unsigned_chars);
    H5Tclose(signed_chars);
    if (registered < 0) {
      throw std::runtime_error("libhdf5: cannot register the checked variable-length string "
                               "conversion");
    }
  });
}

// A file as opened: what a cached scan belongs to.
using FileKey = std::tuple<dev_t, ino_t, off_t, std::int64_t>;
struct HeapCache {
  std::mutex mutex;
  std::map<FileKey, std::shared_ptr<const GlobalHeapObjects>> scans;
};
HeapCache& heapCache() {
  static HeapCache cache;
  return cache;
}

// The descriptor of a read-only file opened with the default (sec2) driver, else -1.
int readOnlyDescriptor(hid_t file) {
  unsigned intent = 0;
  if (H5Fget_intent(file, &intent) < 0 || (intent & H5F_ACC_RDWR) != 0) return -1;
  const hid_t fapl = H5Fget_access_plist(file);
  void* handle = nullptr;
  const bool sec2 = fapl >= 0 && H5Pget_driver(fapl) == H5FD_SEC2 &&
                    H5Fget_vfd_handle(file, fapl, &handle) >= 0 && handle != nullptr;
  if (fapl >= 0) H5Pclose(fapl);
  return sec2 ? *static_cast<int*>(handle) : -1;
}

std::optional<FileKey> keyOf(int fd, struct stat* st) {
  if (fd < 0 || fstat(fd, st) != 0) return std::nullopt;
  return FileKey{st->st_dev, st->st_ino, st->st_size,
                 std::int64_t{st->st_mtim.tv_sec} * 1000000000 + st->st_mtim.tv_nsec};
}

// The identifier of the file `object` lives in, closed at scope exit.
struct FileOf {
  explicit FileOf(hid_t object) : id(H5Iget_file_id(object)) {}
  ~FileOf() {
    if (id >= 0) H5Fclose(id);
  }
  FileOf(const FileOf&) = delete;
  FileOf& operator=(const FileOf&) = delete;
  hid_t id;
};

}  // namespace

herr_t readVlenStrings(hid_t attr, hid_t mem_type, char** out, const GlobalHeapObjects* heaps,
                       std::string* refusal) {
  if (heaps == nullptr) return H5Aread(attr, mem_type, out);
  registerCheckedConversion();
  ReadContext context{heaps, std::nullopt};
  t_read = &context;
  const herr_t read = H5Aread(attr, mem_type, out);
  t_read = nullptr;
  if (context.refusal) {
    H5Eclear2(H5E_DEFAULT);
    *refusal = *context.refusal;
  }
  return read;
}

std::shared_ptr<const GlobalHeapObjects> heapObjectsOf(hid_t object) {
  const FileOf file(object);
  const int fd = readOnlyDescriptor(file.id);
  struct stat st {};
  const auto key = keyOf(fd, &st);
  if (!key) return nullptr;
  HeapCache& cache = heapCache();
  {
    const std::lock_guard<std::mutex> lock(cache.mutex);
    if (const auto it = cache.scans.find(*key); it != cache.scans.end()) return it->second;
  }
  // The file libhdf5 has open, even if its path now names another one.
  const auto bytes = readFileBytes("/proc/self/fd/" + std::to_string(fd));
  auto scan = std::make_shared<const GlobalHeapObjects>(
      bytes ? scanGlobalHeaps(*bytes) : GlobalHeapObjects{});
  rememberHeapObjects(file.id, scan);
  return scan;
}

void rememberHeapObjects(hid_t file, std::shared_ptr<const GlobalHeapObjects> objects) {
  struct stat st {};
  const auto key = keyOf(readOnlyDescriptor(file), &st);
  if (!key) return;
  HeapCache& cache = heapCache();
  const std::lock_guard<std::mutex> lock(cache.mutex);
  constexpr std::size_t kFiles = 64;  // a few KB each; tables read hundreds of files in turn
  if (cache.scans.size() >= kFiles) cache.scans.erase(cache.scans.begin());
  cache.scans[*key] = std::move(objects);
}

}  // namespace marglab::h5::detail
