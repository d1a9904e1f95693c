#include "core/io/hdf5_global_heap.h"

#include <algorithm>
#include <fstream>

namespace marglab::h5::detail {

namespace {

// Where the superblock starts (byte 0, 512, 1024, 2048, ...: after a user block) and its "size
// of lengths" (bytes of an object size: byte 14 of a version 0/1 superblock, byte 10 of a version
// 2/3 one). Byte 0 and 8 (libhdf5's default) when no superblock is recognised.
struct Superblock {
  std::uint64_t at = 0;
  int lengths = 8;
};
Superblock superblockOf(const std::vector<unsigned char>& file) {
  static const unsigned char kSignature[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
  for (std::uint64_t at = 0; at + 16 <= file.size(); at = at == 0 ? 512 : 2 * at) {
    if (!std::equal(kSignature, kSignature + 8, file.begin() + static_cast<std::ptrdiff_t>(at))) {
      continue;
    }
    const int version = file[at + 8];
    const int lengths = version <= 1 ? file[at + 14] : file[at + 10];
    return {at, lengths == 2 || lengths == 4 || lengths == 8 ? lengths : 8};
  }
  return {};
}

// The walk libhdf5 makes over the collection [begin, end), recording each object of index > 0
// under (collection, index); the offset of the first object whose step is 0 or wraps (the walk
// never ends) or whose bytes run past the end (H5HG_read copies them from beyond the
// collection), with which of the two; nullopt when every object is inside.
struct BadObject {
  std::uint64_t at;
  const char* why;
};
std::optional<BadObject> walkCollection(const std::vector<unsigned char>& file,
                                        std::uint64_t begin, std::uint64_t end, int lengths,
                                        std::uint64_t collection, GlobalHeapObjects& objects) {
  const std::uint64_t header = 8 + static_cast<std::uint64_t>(lengths);
  for (std::uint64_t p = begin; p < end && end - p >= header;) {
    const std::uint64_t index = littleEndian(&file[p], 2);
    const std::uint64_t size = littleEndian(&file[p + 8], lengths);
    const std::uint64_t padded = (size + 7) & ~std::uint64_t{7};  // wraps to 0 as libhdf5's does
    const std::uint64_t step = index > 0 ? header + padded : size;
    // libhdf5 adds the step to a pointer: a step of half the address space or more goes back.
    if (step == 0 || step >= (std::uint64_t{1} << 62)) return BadObject{p, "does not advance"};
    const std::uint64_t bytes = index > 0 ? header + size : size;
    if (size > end - p || bytes > end - p) return BadObject{p, "runs past the collection's end"};
    if (index > 0) objects.size[{collection, index}] = size;
    p += step;
  }
  return std::nullopt;
}

}  // namespace

GlobalHeapObjects scanGlobalHeaps(const std::vector<unsigned char>& file) {
  GlobalHeapObjects objects;
  const Superblock superblock = superblockOf(file);
  const int lengths = superblock.lengths;
  const std::uint64_t prefix = 8 + static_cast<std::uint64_t>(lengths);  // GCOL, version, size
  static const unsigned char kGcol[4] = {'G', 'C', 'O', 'L'};
  for (auto it = std::search(file.begin(), file.end(), kGcol, kGcol + 4); it != file.end();
       it = std::search(it + 1, file.end(), kGcol, kGcol + 4)) {
    const auto at = static_cast<std::uint64_t>(it - file.begin());
    if (file.size() - at < prefix || file[at + 4] != 1 || at < superblock.at) continue;
    const std::uint64_t size = littleEndian(&file[at + 8], lengths);
    if (size < prefix || size > file.size() - at) continue;
    const auto object =
        walkCollection(file, at + prefix, at + size, lengths, at - superblock.at, objects);
    if (object && !objects.bad) {
      objects.bad = "global heap collection at byte " + std::to_string(at) +
                    ": the object at byte " + std::to_string(object->at) + " has index " +
                    std::to_string(littleEndian(&file[object->at], 2)) + " and size " +
                    std::to_string(littleEndian(&file[object->at + 8], lengths)) + ", which " +
                    object->why;
    }
  }
  return objects;
}

std::optional<std::vector<unsigned char>> readFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return std::nullopt;
  const std::streamoff size = std::max<std::streamoff>(in.tellg(), 0);
  std::vector<unsigned char> file(static_cast<std::size_t>(size));
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(file.data()), static_cast<std::streamsize>(file.size()))) {
    return std::nullopt;
  }
  return file;
}

}  // namespace marglab::h5::detail
