#pragma once
// Variable-length strings read from a file checked before libhdf5 reads them. On disk such a
// string is a descriptor in the attribute — its length in bytes (4), then the heap ID of its
// bytes: a global heap collection's address (size of offsets) and an object index (4) — and
// libhdf5 1.10 trusts both (fuzz_track_hdf5's findings): it allocates the claimed length before
// it looks at the heap object (a 44 KB file claiming 4 GB made `marglab run --tracks` hold
// 8 GB), copies the object's own size into that buffer whatever the claim, and follows an index
// of 0 to the collection's free space (a read before the collection's end). No public API gives
// the descriptors, but a datatype conversion sees them: the conversion from a variable-length
// string to a variable-length string is registered here as a soft conversion that checks every
// descriptor — a string of the file's global heap whose size is the claimed length times the
// size of a character, which libhdf5 reads from the file too (1 byte as written, but a fuzzed
// 4-byte field made a 14-byte string claim 9.9 GB) — and then calls libhdf5's own
// conversion (H5Tfind). It checks only inside readVlenStrings, the reads of read-only files, with
// the heap scanned when File::openReadOnly opened the file (held by each Object of it: no global
// cache keyed by the file's identity, and each opening sees the file as it is); elsewhere it is
// libhdf5's conversion.

#include <hdf5.h>

#include <string>

#include "core/io/hdf5_global_heap.h"

namespace marglab::h5::detail {

// H5Aread(attr, mem_type, out) of a variable-length string attribute of `n` strings of the file
// of `heaps`, its stored bytes and each descriptor checked first (unchecked when heaps is nullptr:
// a file marglab is writing).
// Returns H5Aread's result; when a descriptor is refused, nothing is read, the result is negative
// and *refusal says why ("string 0 claims 4294967280 bytes; its global heap object (collection at
// address 2048, index 1) holds 14"), with HDF5's error stack cleared.
herr_t readVlenStrings(hid_t attr, hid_t mem_type, std::size_t n, char** out,
                       const GlobalHeapObjects* heaps, std::string* refusal);

}  // namespace marglab::h5::detail
