// libFuzzer harness: text track files (core/sim/track_io.h, readTracksText).

#include <cstdint>

#include "core/sim/track_io.h"
#include "fuzz/fuzz_input.h"

using namespace marglab;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::writeInput(data, size, ".tracks.txt");
  fuzz::expectInputErrorOrSuccess([&] { readTracksText(path); });
  return 0;
}
