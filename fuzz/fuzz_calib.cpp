// libFuzzer harness: the calibration parsers (core/data/parsers.h: EuRoC sensor.yaml, Kalibr
// camchain and IMU yaml, KITTI calib.txt). The first byte picks the parser, the rest is the file.

#include <cstdint>

#include "core/data/parsers.h"
#include "fuzz/fuzz_input.h"

using namespace marglab;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string path = fuzz::writeInput(data + 1, size - 1, ".yaml");
  fuzz::expectInputErrorOrSuccess([&] {
    switch (data[0] % 4) {
      case 0:
        readEurocSensorYaml(path);
        break;
      case 1:
        readKalibrCamchain(path);
        break;
      case 2:
        readKalibrImuNoise(path);
        break;
      default:
        readKittiCalib(path);
        break;
    }
  });
  return 0;
}
