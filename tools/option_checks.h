#pragma once
// CLI11 validators shared by the verbs: option values are checked while the command line is
// parsed, so `marglab run` and the sweep validation (which parses a sweep's `args` with the real
// `run` verb) reject them before anything runs: a bad value with exit code 2 (usage error), a
// missing input path or dataset with exit code 1 (input error, `existingPath`).

#include <fmt/core.h>
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/pipeline/run_config.h"

namespace marglab::cli {

// An option that sets an estimator config key: the key's range (docs/design.md §9).
inline CLI::Validator configKeyRange(const std::string& key) {
  return CLI::Validator([key](std::string& text) { return RunConfig::checkValueText(key, text); },
                        "", "config " + key);
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
          return fmt::format("{}: expected an integer in [0, {}]", shortToken(text),
                             std::numeric_limits<std::uint64_t>::max());
        }
        return {};
      },
      "", "seed");
}

// An integer in [lo, hi] (CLI::NonNegativeNumber / PositiveNumber print a 309-digit range and
// accept fractions).
inline CLI::Validator intRange(const char* what, long long lo, long long hi) {
  return CLI::Validator(
      [what, lo, hi](std::string& text) -> std::string {
        long long value = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, value);
        if (text.empty() || ec != std::errc() || ptr != end || value < lo || value > hi) {
          return fmt::format("{}: expected {}, an integer in [{}, {}]", shortToken(text), what, lo,
                             hi);
        }
        return {};
      },
      "", "int");
}

// A finite number in (0, hi].
inline CLI::Validator positiveReal(const char* what, double hi) {
  return CLI::Validator(
      [what, hi](std::string& text) -> std::string {
        double value = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, value);
        if (text.empty() || ec != std::errc() || ptr != end || !(value > 0 && value <= hi)) {
          return fmt::format("{}: expected {}, a number in (0, {:g}]", shortToken(text), what, hi);
        }
        return {};
      },
      "", "number");
}

// The number of parallel jobs, 0 meaning one per core; bounded like lm.threads.
inline CLI::Validator jobCount() {
  return intRange("the number of parallel jobs (0: cores)", 0, 256);
}

// A count that must be >= 0 and fit an int.
inline CLI::Validator nonNegativeInt(const char* what) {
  return intRange(what, 0, std::numeric_limits<int>::max());
}

// A count that must be >= 1 and fit an int.
inline CLI::Validator positiveInt(const char* what) {
  return intRange(what, 1, std::numeric_limits<int>::max());
}

// A dataset argument is a shipped sequence name or an existing folder; anything else is a missing
// input (exit 1, like a missing file) and the message lists the names.
inline void checkDatasetArgument(const std::string& dataset) {
  if (std::filesystem::is_directory(dataset)) return;
  const std::vector<std::string> names = listSequences();
  if (std::find(names.begin(), names.end(), dataset) != names.end()) return;
  throw InputError({}, 0,
                   fmt::format("unknown dataset '{}': expected a folder or one of {}",
                               shortToken(dataset), fmt::join(names, ", ")));
}

enum class PathKind { kFile, kFolder };

// A path argument that must exist. A missing or unreadable file is bad input, not bad usage: the
// validator throws InputError (exit 1, docs/design.md §7) instead of returning CLI11's message
// (exit 2). It runs while the command line is parsed, so a sweep's `args` are checked too.
inline CLI::Validator existingPath(const std::string& option, PathKind kind) {
  const bool want_folder = kind == PathKind::kFolder;
  return CLI::Validator(
      [option, want_folder](std::string& path) -> std::string {
        std::error_code ec;
        const auto status = std::filesystem::status(path, ec);
        const char* expected = want_folder ? "folder" : "file";
        if (ec && ec != std::errc::no_such_file_or_directory) {
          throw InputError(
              {}, 0,
              fmt::format("{} {}: cannot access it: {}", option, shortToken(path), ec.message()));
        }
        if (!std::filesystem::exists(status)) {
          throw InputError({}, 0,
                           fmt::format("{} {}: no such {}", option, shortToken(path), expected));
        }
        if (std::filesystem::is_directory(status) != want_folder) {
          throw InputError({}, 0,
                           fmt::format("{} {}: expected a {}, found a {}", option, shortToken(path),
                                       expected, want_folder ? "file" : "folder"));
        }
        return {};
      },
      want_folder ? "FOLDER" : "FILE", "existing " + option);
}

}  // namespace marglab::cli
