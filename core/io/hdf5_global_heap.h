#pragma once
// A guard against corrupted HDF5 files that libhdf5 1.10 (Debian bookworm) does not survive,
// found by fuzz_track_hdf5. A global heap collection (HDF5 file format spec, section III.E,
// signature "GCOL") holds the data of variable-length strings as a run of objects, each with a
// header
//   heap object index (2 bytes), reference count (2), reserved (4), object size (L bytes)
// followed by its data padded to 8 bytes; index 0 is the free space and has no padding. libhdf5
// walks the run by advancing 2 + 2 + 4 + L + align8(size) bytes per object (size bytes for index
// 0) until the end of the collection, and H5HG_read copies an object's size bytes from it. Two
// corruptions it does not check: a free-space object of size 0, or a size that makes the step
// wrap around the address space, never advances, and H5Aread loops forever; an object whose size
// runs past the collection's end is copied from beyond it (an out-of-bounds read). The walk is
// repeated here on the file's bytes before libhdf5 opens it, and it records every object's size:
// a string's descriptor (its length and heap ID, in the attribute) is checked against it before
// libhdf5 reads the string (hdf5_vlen_check.h).

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace marglab::h5::detail {

struct GlobalHeapObjects {
  // Size in bytes of every object of index > 0, by (collection address, object index); the
  // address as the file's descriptors give it (relative to the superblock's base address).
  std::map<std::pair<std::uint64_t, std::uint64_t>, std::uint64_t> size;
  // The first global heap collection with an object libhdf5 would not survive ("global heap
  // collection at byte 2048: the object at byte 2304 has index 0 and size 0, which does not
  // advance"), or nullopt. Byte runs that carry the signature but not a collection (version ≠ 1,
  // or a size beyond the end of the file) are skipped: libhdf5 refuses those itself.
  std::optional<std::string> bad;
};

GlobalHeapObjects scanGlobalHeaps(const std::vector<unsigned char>& file);

// The unsigned integer of `bytes` little-endian bytes at p (HDF5 stores every field so).
inline std::uint64_t littleEndian(const unsigned char* p, std::size_t bytes) {
  std::uint64_t v = 0;
  for (std::size_t i = bytes; i-- > 0;) v = (v << 8) | p[i];
  return v;
}

// The whole file, or nullopt when it cannot be read (libhdf5 then says why).
std::optional<std::vector<unsigned char>> readFileBytes(const std::string& path);

}  // namespace marglab::h5::detail
