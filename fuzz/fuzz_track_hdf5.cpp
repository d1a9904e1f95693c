// libFuzzer harness: HDF5 track files (core/sim/track_io.h, readTracksHdf5). libhdf5 itself is not
// instrumented: the fuzzer explores the file's structure only as far as marglab's checks see it.

#include <cstdint>

#include "core/sim/track_io.h"
#include "fuzz/fuzz_input.h"

using namespace marglab;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::writeInput(data, size, ".tracks.h5");
  fuzz::expectInputErrorOrSuccess([&] { readTracksHdf5(path); });
  return 0;
}
