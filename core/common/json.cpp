#include "core/common/json.h"

#include <fmt/core.h>

#include <cstdlib>

namespace marglab {

double roundedTo(double x, int significant) {
  return std::strtod(fmt::format("{:.{}e}", x, significant - 1).c_str(), nullptr);
}

}  // namespace marglab
