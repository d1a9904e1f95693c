#include "core/io/hdf5_vlen_check.h"

#include <cstdint>
#include <mutex>
#include <optional>
#include <stdexcept>

namespace marglab::h5::detail {

namespace {

// The first descriptor of `n` (each `size` bytes, `stride` apart) that is not a string of
// `heaps` with `char_size`-byte characters, with why; nullopt when all are. A null string
// (address 0) is not read by libhdf5.
std::optional<std::string> refuseDescriptor(const unsigned char* buf, std::size_t n,
                                            std::size_t size, std::size_t stride,
                                            std::uint64_t char_size,
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
    // libhdf5 allocates length × char_size bytes (< 2^64: both fit in 4 bytes on disk).
    if (it->second != length * char_size) {
      const std::string claim =
          char_size == 1 ? std::to_string(length) + " bytes"
                         : std::to_string(length) + " characters of " +
                               std::to_string(char_size) + " bytes";
      return "string " + std::to_string(i) + " claims " + claim + "; its " + object + " holds " +
             std::to_string(it->second);
    }
  }
  return std::nullopt;
}

// The size of one character of a variable-length string type: 1 as libhdf5 writes it, but read
// from the file's datatype message, so any 4-byte value there (fuzz/README.md: a 14-byte string
// of 704 MB characters made `marglab run --tracks` hold 9.7 GB).
std::optional<std::size_t> characterSize(hid_t string_type) {
  const hid_t character = H5Tget_super(string_type);
  if (character < 0) return std::nullopt;
  const std::size_t size = H5Tget_size(character);
  H5Tclose(character);
  return size == 0 ? std::nullopt : std::optional<std::size_t>(size);
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
    const std::optional<std::size_t> char_size = characterSize(src);
    t_read->refusal =
        char_size ? refuseDescriptor(static_cast<const unsigned char*>(buf), n, size,
                                     buf_stride == 0 ? size : buf_stride, *char_size,
                                     *t_read->heaps)
                  : "the string's character type cannot be read";
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

// libhdf5 sizes an attribute's stored bytes by the descriptor size its datatype message gives,
// but reads n descriptors of the size the superblock implies (length 4, address, index 4): a
// message claiming 14 bytes made it read 16 from a 14-byte buffer (fuzz_track_hdf5). Why the
// stored bytes are not n such descriptors, or nullopt.
std::optional<std::string> refuseStorage(hid_t attr, std::size_t n) {
  const hid_t file = H5Iget_file_id(attr);
  const hid_t fcpl = file < 0 ? -1 : H5Fget_create_plist(file);
  std::size_t offsets = 0;
  const bool sized = fcpl >= 0 && H5Pget_sizes(fcpl, &offsets, nullptr) >= 0;
  if (fcpl >= 0) H5Pclose(fcpl);
  if (file >= 0) H5Fclose(file);
  if (!sized) return "the file's size of offsets cannot be read";
  const std::size_t descriptor = 8 + offsets;
  const hsize_t stored = H5Aget_storage_size(attr);
  if (stored == n * descriptor) return std::nullopt;
  return "it stores " + std::to_string(stored) + " bytes, not " + std::to_string(n) +
         (n == 1 ? " string descriptor" : " string descriptors") + " of " +
         std::to_string(descriptor) + " bytes";
}

}  // namespace

herr_t readVlenStrings(hid_t attr, hid_t mem_type, std::size_t n, char** out,
                       const GlobalHeapObjects* heaps, std::string* refusal) {
  if (heaps == nullptr) return H5Aread(attr, mem_type, out);
  if (auto storage = refuseStorage(attr, n)) {
    *refusal = *storage;
    return -1;
  }
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

}  // namespace marglab::h5::detail
