// libFuzzer harness: HDF5 track files read in this process through libhdf5 (readTrackFileContent),
// then checked (tracksFromContent) — the campaign through libhdf5, not run by CI (fuzz/README.md).
// libhdf5 is not instrumented, so the fuzzer explores the file's structure only as far as
// marglab's code sees it; its crashes, loops and huge allocations are findings of libhdf5, which
// `marglab` contains by reading a user's file in a child first (core/io/hdf5_trust.h).

#include <cstdint>

#include "core/sim/track_io.h"
#include "fuzz/fuzz_input.h"

using namespace marglab;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::writeInput(data, size, ".tracks.h5");
  fuzz::expectInputErrorOrSuccess([&] { tracksFromContent(path, readTrackFileContent(path)); });
  return 0;
}
