// libFuzzer harness: the line-based dataset parsers (core/data/parsers.h). The first byte picks the
// parser, the rest is the file (plain or gzip: TextFile reads both).

#include <cstdint>
#include <vector>

#include "core/data/parsers.h"
#include "fuzz/fuzz_input.h"

using namespace marglab;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string path = fuzz::writeInput(data + 1, size - 1, ".txt");
  fuzz::expectInputErrorOrSuccess([&] {
    switch (data[0] % 6) {
      case 0:
        readTumTrajectory(path);
        break;
      case 1:
        readAslGroundTruth(path);
        break;
      case 2:
        readAslImu(path);
        break;
      case 3:
        readTimestampList(path);
        break;
      case 4:
        readKittiTimes(path);
        break;
      default: {
        // One time per line, so that the pose count check passes for well-formed files and the
        // fuzzer reaches the per-pose checks.
        std::vector<int64_t> t_ns;
        for (std::size_t i = 1; i < size; ++i) {
          if (data[i] == '\n') t_ns.push_back(static_cast<int64_t>(t_ns.size()) * 100'000'000);
        }
        readKittiPoses(path, t_ns);
      }
    }
  });
  return 0;
}
