// libFuzzer harness: the estimator's TOML config (RunConfig::loadTomlString, then the whole
// config's validation). A config that loads and validates must also survive its own round trip.

#include <cstdint>
#include <cstdlib>
#include <string>

#include "core/common/error.h"
#include "core/pipeline/run_config.h"

using namespace marglab;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  RunConfig config;
  try {
    config.loadTomlString(text, "fuzz.toml");
    config.validate();
  } catch (const InputError&) {
    return 0;
  }
  // Outside the InputError catch: a valid config whose TOML does not read back is a finding.
  RunConfig again;
  again.loadTomlString(config.toToml(), "round-trip.toml");
  if (again.toToml() != config.toToml()) std::abort();
  return 0;
}
