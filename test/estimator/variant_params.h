#pragma once
// The five double-precision variants as a gtest parameter list, with readable test names.

#include <gtest/gtest.h>

#include <algorithm>
#include <string>

namespace marglab::test {

inline auto doublePrecisionVariants() {
  return ::testing::Values("ns-qr-sqrt-f64", "sc-sc-sq-f64", "sc-qr-sqrt-f64", "ns-sc-sqrt-f64",
                           "sc-sc-sqrt-f64");
}

// "ns-qr-sqrt-f64" → "ns_qr_sqrt_f64".
inline std::string variantTestName(const ::testing::TestParamInfo<std::string>& info) {
  std::string name = info.param;
  std::replace(name.begin(), name.end(), '-', '_');
  return name;
}

}  // namespace marglab::test
