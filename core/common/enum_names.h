#pragma once
// One name table per enum: the value ↔ name pairs from which the parser, the CLI's choice lists,
// the help text, the spec and config files and the results files all take their spelling, so that
// no enum value is compared as a string anywhere else.
//
//   inline constexpr EnumNames<RunMode, 3> kRunModeNames{{{RunMode::kAuto, "auto"}, ...}};
//   nameOf(kRunModeNames, RunMode::kVo)            → "vo"
//   parseName(kRunModeNames, "vio", &mode)         → true, mode = kVio
//   namesOf(kRunModeNames)                         → {"auto", "vo", "vio"} (CLI11 IsMember)
//   describeNames(kRunModeNames)                   → "auto, vo or vio" (messages, help)

#include <array>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace marglab {

template <typename E>
struct EnumName {
  E value;
  const char* name;
};

template <typename E, std::size_t N>
using EnumNames = std::array<EnumName<E>, N>;

template <typename E, std::size_t N>
const char* nameOf(const EnumNames<E, N>& table, E value) {
  for (const EnumName<E>& entry : table) {
    if (entry.value == value) return entry.name;
  }
  throw std::logic_error("nameOf: an enum value without a name");
}

// False (and *out unchanged) for a name not in the table.
template <typename E, std::size_t N>
bool parseName(const EnumNames<E, N>& table, std::string_view text, E* out) {
  for (const EnumName<E>& entry : table) {
    if (text == entry.name) {
      *out = entry.value;
      return true;
    }
  }
  return false;
}

template <typename E, std::size_t N>
std::vector<std::string> namesOf(const EnumNames<E, N>& table) {
  std::vector<std::string> names;
  for (const EnumName<E>& entry : table) names.emplace_back(entry.name);
  return names;
}

// "a", "a or b", "a, b or c"; quoted: "\"a\", \"b\" or \"c\"" (as TOML strings).
template <typename E, std::size_t N>
std::string describeNames(const EnumNames<E, N>& table, bool quoted = false) {
  const std::string quote = quoted ? "\"" : "";
  std::string text;
  for (std::size_t k = 0; k < N; ++k) {
    if (k > 0) text += k + 1 == N ? " or " : ", ";
    text += quote + table[k].name + quote;
  }
  return text;
}

}  // namespace marglab
