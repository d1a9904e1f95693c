#include "core/common/config_bindings.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <toml++/toml.h>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <sstream>
#include <stdexcept>

namespace marglab {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

bool accepts(const Rule& rule, double v) {
  if (rule.has_sentinel && v == rule.sentinel) return true;
  if (!std::isfinite(v)) return false;
  if (rule.lo_open ? v <= rule.lo : v < rule.lo) return false;
  if (rule.hi_open ? v >= rule.hi : v > rule.hi) return false;
  return true;
}

std::string numberText(double v, bool integer) {
  if (integer && std::isfinite(v) && std::abs(v) < 9.2e18) {
    return std::to_string(static_cast<std::int64_t>(v));
  }
  return fmt::format("{}", v);
}

// "an integer in [1, 1000]", "a finite number > 0", "-1 (dataset default) or ...".
std::string describe(const Rule& rule, bool integer) {
  const std::string kind = integer ? "an integer" : "a finite number";
  std::string text;
  if (std::isfinite(rule.lo) && std::isfinite(rule.hi)) {
    text = fmt::format("{} in {}{}, {}{}", kind, rule.lo_open ? "(" : "[",
                       numberText(rule.lo, integer), numberText(rule.hi, integer),
                       rule.hi_open ? ")" : "]");
  } else if (std::isfinite(rule.lo)) {
    text = fmt::format("{} {} {}", kind, rule.lo_open ? ">" : ">=", numberText(rule.lo, integer));
  } else if (std::isfinite(rule.hi)) {
    text = fmt::format("{} {} {}", kind, rule.hi_open ? "<" : "<=", numberText(rule.hi, integer));
  } else {
    text = kind;
  }
  if (rule.has_sentinel) {
    text = fmt::format("{} ({}) or {}", numberText(rule.sentinel, integer), rule.sentinel_meaning,
                       text);
  }
  return text;
}

// An integer TOML value: exact integers, and floats with an integral value (1e3), as int64.
std::optional<std::int64_t> integerValue(const toml::node& node, bool* out_of_range) {
  *out_of_range = false;
  if (node.is_integer()) return node.value<std::int64_t>();
  if (const auto f = node.value_exact<double>()) {
    if (std::isfinite(*f) && std::floor(*f) == *f) {
      if (std::abs(*f) >= 9.2e18) {
        *out_of_range = true;
        return std::nullopt;
      }
      return static_cast<std::int64_t>(*f);
    }
  }
  return std::nullopt;
}

// A TOML array of numbers, each checked against the binding's rule.
template <typename Error>
std::vector<double> numberList(const Binding& binding, const toml::node& node, Error error) {
  const toml::array* array = node.as_array();
  if (array == nullptr) {
    throw error(node, fmt::format("expected a list of numbers for {} ([] for the default)",
                                  binding.name()));
  }
  std::vector<double> values;
  for (std::size_t k = 0; k < array->size(); ++k) {
    const auto v = (*array)[k].value<double>();
    if (!v || !accepts(binding.rule, *v)) {
      throw error(node, fmt::format("{}[{}]: expected {}", binding.name(), k,
                                    describe(binding.rule, false)));
    }
    values.push_back(*v);
  }
  return values;
}

// An integer key's value, checked as int64 before narrowing: a value outside the range never
// wraps.
template <typename Error>
void setInteger(const Binding& binding, const toml::node& node, Error error) {
  bool out_of_range = false;
  const auto v = integerValue(node, &out_of_range);
  if (out_of_range) {
    throw error(node, fmt::format("{} = {}: expected {}", binding.name(), *node.value<double>(),
                                  describe(binding.rule, true)));
  }
  if (!v) {
    throw error(node,
                fmt::format("expected {} for {}", describe(binding.rule, true), binding.name()));
  }
  if (!accepts(binding.rule, static_cast<double>(*v))) {
    throw error(node, fmt::format("{} = {}: expected {}", binding.name(), *v,
                                  describe(binding.rule, true)));
  }
  if (binding.i != nullptr) {
    *binding.i = static_cast<int>(*v);
  } else {
    *binding.u = static_cast<std::uint64_t>(*v);
  }
}

template <typename Error>
void setValue(const Binding& binding, const toml::node& node, Error error) {
  if (binding.d != nullptr) {
    auto v = node.value<double>();
    if (!v) throw error(node, fmt::format("expected a number for {}", binding.name()));
    if (!accepts(binding.rule, *v)) throw error(node, binding.problem(*v));
    *binding.d = *v;
  } else if (binding.integer()) {
    setInteger(binding, node, error);
  } else if (binding.list != nullptr) {
    *binding.list = numberList(binding, node, error);
  } else if (binding.b != nullptr) {
    // value<bool>() would also convert an integer (enabled = 1): only TOML's true and false count.
    auto v = node.value_exact<bool>();
    if (!v) throw error(node, fmt::format("expected true or false for {}", binding.name()));
    *binding.b = *v;
  } else {
    auto v = node.value<std::string>();
    if (!v || !binding.parse_choice(*v)) {
      throw error(node, fmt::format("expected {} for {}", binding.choices, binding.name()));
    }
  }
}

bool bindsSection(const Bindings& bindings, const std::string& section) {
  return std::any_of(bindings.begin(), bindings.end(),
                     [&](const Binding& b) { return section == b.section; });
}

void apply(const Bindings& bindings, const toml::table& root, const std::string& name,
           const TomlScope& scope, ConfigOrigins* origins) {
  auto error = [&](const toml::node& node, const std::string& what) {
    return InputError(name, static_cast<int>(node.source().begin.line), what);
  };
  for (const auto& [section_key, section_node] : root) {
    const std::string section(section_key.str());
    if (section == scope.foreign_section) continue;
    if (scope.skip_unbound_sections && !bindsSection(bindings, section)) continue;
    const toml::table* table = section_node.as_table();
    if (table == nullptr) throw error(section_node, "expected a table [" + section + "]");
    for (const auto& [key_key, node] : *table) {
      const std::string key(key_key.str());
      auto it = std::find_if(bindings.begin(), bindings.end(), [&](const Binding& b) {
        return section == b.section && key == b.key;
      });
      if (it == bindings.end()) throw error(node, fmt::format("unknown key {}.{}", section, key));
      setValue(*it, node, error);
      (*origins)[it->name()] = ConfigOrigin{name, static_cast<int>(node.source().begin.line), ""};
    }
  }
}

bool isToml(const std::string& text) {
  try {
    static_cast<void>(toml::parse(text));
    return true;
  } catch (const toml::parse_error&) {
    return false;
  }
}

}  // namespace

Rule atLeast(double lo) { return Rule{lo}; }
Rule above(double lo) { return Rule{lo, kInf, true}; }
Rule between(double lo, double hi) { return Rule{lo, hi}; }
Rule orSentinel(Rule rule, double sentinel, const char* meaning) {
  rule.has_sentinel = true;
  rule.sentinel = sentinel;
  rule.sentinel_meaning = meaning;
  return rule;
}

std::string Binding::problem(double v) const {
  return fmt::format("{} = {}: expected {}", name(), numberText(v, integer()),
                     describe(rule, integer()));
}

std::string ConfigOrigin::describe() const {
  if (!option.empty()) return option;
  if (file.empty()) return "";
  return line > 0 ? fmt::format("{}:{}", file, line) : file;
}

void applyToml(const Bindings& bindings, const std::string& text, const std::string& name,
               const TomlScope& scope, ConfigOrigins* origins) {
  try {
    apply(bindings, toml::parse(text, name), name, scope, origins);
  } catch (const toml::parse_error& e) {
    throw InputError(name, static_cast<int>(e.source().begin.line), std::string(e.description()));
  }
}

void applyAssignment(const Bindings& bindings, const std::string& assignment,
                     const std::string& option, ConfigOrigins* origins) {
  const std::size_t eq = assignment.find('=');
  const std::string key = assignment.substr(0, eq);
  const std::size_t dot = key.find('.');
  const auto name_char = [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
  };
  const bool well_formed =
      eq != std::string::npos && dot != std::string::npos && dot > 0 && dot + 1 < key.size() &&
      std::all_of(key.begin(), key.begin() + static_cast<std::ptrdiff_t>(dot), name_char) &&
      std::all_of(key.begin() + static_cast<std::ptrdiff_t>(dot) + 1, key.end(), name_char) &&
      assignment.find_first_of("\r\n", eq) == std::string::npos;
  if (!well_formed) {
    throw UsageError(fmt::format("{} {}: expected section.key=value, e.g. lm.max_iterations=3",
                                 option, shortToken(assignment)));
  }
  const std::string value = assignment.substr(eq + 1);
  const auto toml_text = [&](const std::string& v) {
    return fmt::format("[{}]\n{} = {}\n", key.substr(0, dot), key.substr(dot + 1), v);
  };
  // A name (relative, basalt) may be given without TOML's quotes.
  const bool bare = value.find_first_of("\"'[]{}\n") == std::string::npos;
  std::string text = toml_text(value);
  if (bare && !isToml(text)) text = toml_text("\"" + value + "\"");
  try {
    applyToml(bindings, text, "--set", TomlScope{}, origins);
  } catch (const InputError& e) {
    throw UsageError(fmt::format("{} {}: {}", option, shortToken(assignment), e.detail()));
  }
  (*origins)[key] = ConfigOrigin{"", 0, option};
}

std::string bindingsToToml(const Bindings& bindings) {
  toml::table root;
  for (const Binding& b : bindings) {
    if (!root.contains(b.section)) root.insert(b.section, toml::table{});
    toml::table& section = *root[b.section].as_table();
    if (b.d != nullptr) {
      section.insert(b.key, *b.d);
    } else if (b.i != nullptr) {
      section.insert(b.key, static_cast<int64_t>(*b.i));
    } else if (b.b != nullptr) {
      section.insert(b.key, *b.b);
    } else if (b.u != nullptr) {
      section.insert(b.key, static_cast<int64_t>(*b.u));
    } else if (b.list != nullptr) {
      toml::array array;
      for (const double v : *b.list) array.push_back(v);
      section.insert(b.key, std::move(array));
    } else {
      section.insert(b.key, b.print_choice());
    }
  }
  std::ostringstream out;
  out << root;
  return out.str();
}

std::vector<ConfigProblem> rangeProblems(const Bindings& bindings) {
  std::vector<ConfigProblem> out;
  for (const Binding& b : bindings) {
    if (b.numeric() && !accepts(b.rule, b.value())) out.push_back({b.name(), b.problem(b.value())});
    if (b.list == nullptr) continue;
    for (const double v : *b.list) {
      if (!accepts(b.rule, v)) {
        out.push_back({b.name(), fmt::format("{} holds {}: expected numbers that are each {}",
                                             b.name(), v, describe(b.rule, false))});
        break;
      }
    }
  }
  return out;
}

std::string checkBindingText(const Bindings& bindings, const std::string& key,
                             const std::string& text) {
  for (const Binding& b : bindings) {
    if (b.name() != key) continue;
    if (b.parse_choice) {
      return b.parse_choice(text)
                 ? std::string()
                 : fmt::format("{} = {}: expected {}", key, shortToken(text), b.choices);
    }
    if (!b.numeric()) throw std::logic_error("checkValueText: " + key + " is not a number or name");
    const char* begin = text.c_str();
    char* end = nullptr;
    const double v = std::strtod(begin, &end);
    if (text.empty() || end != begin + text.size()) {
      return fmt::format("{} = {}: expected {}", key, text, describe(b.rule, b.integer()));
    }
    if (b.integer() && std::isfinite(v) && std::floor(v) != v) {
      return fmt::format("{} = {}: expected {}", key, text, describe(b.rule, true));
    }
    return accepts(b.rule, v) ? std::string() : b.problem(v);
  }
  throw std::logic_error("checkValueText: unknown config key " + key);
}

std::string relationKey(const ConfigOrigins& origins, const std::string& preferred,
                        const std::vector<std::string>& keys) {
  if (origins.count(preferred) != 0) return preferred;
  for (const std::string& k : keys) {
    if (origins.count(k) != 0) return k;
  }
  return preferred;
}

Problem locateProblem(const ConfigProblem& p, const ConfigOrigins& origins) {
  std::string message = p.message;
  if (!p.related.empty()) {
    std::vector<std::string> where;
    for (const std::string& key : p.related) {
      const auto it = origins.find(key);
      where.push_back(key + " from " +
                      (it == origins.end() ? "the default" : it->second.describe()));
    }
    message += fmt::format(" ({})", fmt::join(where, ", "));
  }
  const auto it = origins.find(p.key);
  if (it == origins.end()) return {ProblemKind::kInput, "config", 0, message};
  if (!it->second.option.empty()) {
    return {ProblemKind::kUsage, "", 0, it->second.option + ": " + message};
  }
  return {ProblemKind::kInput, it->second.file, it->second.line, message};
}

}  // namespace marglab
