#pragma once
// A guard against two kinds of corrupted HDF5 file that libhdf5 1.10 (Debian bookworm) does not
// survive: a global heap collection (HDF5 file format spec, section III.E, signature "GCOL") holds
// the data of variable-length strings as a run of objects, each with a header
//   heap object index (2 bytes), reference count (2), reserved (4), object size (L bytes)
// followed by its data padded to 8 bytes; index 0 is the free space and has no padding. libhdf5
// walks the run by advancing 2 + 2 + 4 + L + align8(size) bytes per object (size bytes for index
// 0) until the end of the collection, and H5HG_read copies an object's size bytes from it. Two
// corruptions it does not check (found by fuzz_track_hdf5): a free-space object of size 0, or a
// size that makes the step wrap around the address space, never advances, and H5Aread loops
// forever; an object whose size runs past the collection's end is copied from beyond it (an
// out-of-bounds read). The walk is repeated here on the file's bytes before libhdf5 opens it.

#include <optional>
#include <string>

namespace marglab::h5::detail {

// A description of the first global heap collection in the file with such an object ("global
// heap collection at byte 2048: the object at byte 2304 has index 0 and size 0, which does not
// advance"), or nullopt. Byte runs that carry the signature but not a collection (version ≠ 1, or
// a size beyond the end of the file) are skipped: libhdf5 refuses those itself.
std::optional<std::string> findBadGlobalHeap(const std::string& path);

}  // namespace marglab::h5::detail
