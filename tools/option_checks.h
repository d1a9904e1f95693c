#pragma once
// CLI11 validators shared by the verbs: option values are checked while the command line is
// parsed, so `marglab run` and the sweep validation (which parses a sweep's `args` with the real
// `run` verb) reject them before anything runs, with exit code 2 (usage error).

#include <fmt/core.h>
#include <CLI/CLI.hpp>

#include <charconv>
#include <cstdint>
#include <limits>
#include <string>

#include "core/estimator/config.h"

namespace marglab::cli {

// An option that sets an estimator config key: the key's range (docs/design.md §9).
inline CLI::Validator configKeyRange(const std::string& key) {
  return CLI::Validator(
      [key](std::string& text) { return EstimatorConfig::checkValueText(key, text); }, "",
      "config " + key);
}

// A seed: a decimal integer in [0, 2^64 − 1]. CLI11 alone turns −1 into 2^64 − 1 and saturates
// values above the range.
inline CLI::Validator seedRange() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        std::uint64_t value = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, value);
        if (text.empty() || ec != std::errc() || ptr != end) {
          return fmt::format("{}: expected an integer in [0, {}]", text,
                             std::numeric_limits<std::uint64_t>::max());
        }
        return {};
      },
      "", "seed");
}

// A count that must be >= 0 and fit an int (CLI::NonNegativeNumber prints a 309-digit range).
inline CLI::Validator nonNegativeInt(const char* what) {
  return CLI::Validator(
      [what](std::string& text) -> std::string {
        long long value = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, value);
        if (text.empty() || ec != std::errc() || ptr != end || value < 0 ||
            value > std::numeric_limits<int>::max()) {
          return fmt::format("{}: expected {}, an integer in [0, {}]", text, what,
                             std::numeric_limits<int>::max());
        }
        return {};
      },
      "", "non-negative int");
}

}  // namespace marglab::cli
