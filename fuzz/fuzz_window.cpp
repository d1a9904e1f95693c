// libFuzzer harness: captured estimator windows (core/estimator/window_io.h, readWindow; plain text
// or gzip).

#include <cstdint>

#include "core/estimator/window_io.h"
#include "fuzz/fuzz_input.h"

using namespace marglab;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::writeInput(data, size, ".win");
  fuzz::expectInputErrorOrSuccess([&] { readWindow(path); });
  return 0;
}
