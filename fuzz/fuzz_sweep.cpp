// libFuzzer harness: sweep definitions (experiments/*.toml, experiment::parseSweep) with every
// validation the CLI does except the `marglab run` option check (the library default accepts every
// option). A fixed list of known sequences keeps the run independent of datasets/.

#include <cstdint>
#include <string>

#include "core/experiment/sweep_def.h"
#include "fuzz/fuzz_input.h"

using namespace marglab;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const experiment::ParseOptions options = [] {
    experiment::ParseOptions o;
    o.known_sequences = {"kitti/00", "kitti/10", "euroc/MH_01_easy", "euroc/V1_01_easy_images",
                         "tumvi/room1"};
    o.known_sequences_given = true;
    return o;
  }();
  const std::string text(reinterpret_cast<const char*>(data), size);
  fuzz::expectInputErrorOrSuccess(
      [&] { experiment::parseSweep(text, "fuzz.toml", "/nonexistent-fuzz-dir", options); });
  return 0;
}
