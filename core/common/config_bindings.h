#pragma once
// The machinery of a config read from TOML: every key is a Binding of a (section, key) to one
// field, with the range or names it accepts. A config is a list of bindings (the estimator's,
// core/estimator/estimator_settings.h, and the run's, core/pipeline/run_config.h, form one list);
// reading, writing, `--set`, range checks and messages are written once here, over any list.
//
// Values are checked as they are read (integers before they are narrowed, so 1e12 is an error and
// never wraps); the messages name the key, the value, the allowed range and where the value came
// from (FILE:LINE of a TOML file, or a command-line option).

#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "core/common/enum_names.h"
#include "core/common/error.h"

namespace marglab {

// Where a config value came from: a TOML file and line, or a command-line option ("--threads").
struct ConfigOrigin {
  std::string file;
  int line = 0;
  std::string option;
  std::string describe() const;  // "cfg.toml:3", "--threads", "" (default)
};

// Where each key ("section.key") was last set; absent: the default.
using ConfigOrigins = std::map<std::string, ConfigOrigin>;

// One invalid value or relation of a config; `message` names the key(s), value(s) and the allowed
// range, without the location (locateProblem adds it).
struct ConfigProblem {
  std::string key;  // "lm.max_iterations"; for a relation, the key the message is about
  std::string message;
  // A relation's keys, whose origins the located message names.
  std::vector<std::string> related = {};
};

// The accepted values of a numeric key: a finite number in [lo, hi] (either end open or
// unbounded), or exactly `sentinel` (e.g. −1 for "dataset default").
struct Rule {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool hi_open = false;
  bool has_sentinel = false;
  double sentinel = 0;
  const char* sentinel_meaning = nullptr;
};

Rule atLeast(double lo);
Rule above(double lo);
Rule between(double lo, double hi);
Rule orSentinel(Rule rule, double sentinel, const char* meaning);

// One TOML key bound to a config field: exactly one of the field pointers, or an enum's parse and
// print (see choice()).
struct Binding {
  const char* section;
  const char* key;
  double* d = nullptr;
  int* i = nullptr;
  bool* b = nullptr;
  std::uint64_t* u = nullptr;
  std::vector<double>* list = nullptr;  // a list of numbers, each in `rule`
  Rule rule = Rule{};                   // numeric keys (d, i, u) and the elements of a list
  // A key with a fixed set of names (an enum field): parse (false for an unknown name), print.
  std::function<bool(const std::string&)> parse_choice = nullptr;
  std::function<std::string()> print_choice = nullptr;
  std::string choices = "";  // for messages: "\"a\" or \"b\""

  std::string name() const { return std::string(section) + "." + key; }
  bool numeric() const { return d != nullptr || i != nullptr || u != nullptr; }
  bool integer() const { return i != nullptr || u != nullptr; }
  double value() const { return d != nullptr ? *d : i != nullptr ? *i : static_cast<double>(*u); }
  // "lm.threads = 0: expected an integer in [1, 256]"
  std::string problem(double v) const;
};

using Bindings = std::vector<Binding>;

inline Binding numberKey(const char* section, const char* key, double* field, Rule rule) {
  Binding binding{section, key, field};
  binding.rule = rule;
  return binding;
}
inline Binding integerKey(const char* section, const char* key, int* field, Rule rule) {
  Binding binding{section, key, nullptr, field};
  binding.rule = rule;
  return binding;
}
inline Binding flagKey(const char* section, const char* key, bool* field) {
  return Binding{section, key, nullptr, nullptr, field};
}
// Binds an enum field to its name table (core/common/enum_names.h).
template <typename E, std::size_t N>
Binding choice(const char* section, const char* key, E* field, const EnumNames<E, N>& names) {
  Binding binding{section, key};
  binding.parse_choice = [field, &names](const std::string& text) {
    return parseName(names, text, field);
  };
  binding.print_choice = [field, &names] { return std::string(nameOf(names, *field)); };
  binding.choices = describeNames(names, true);
  return binding;
}

// Which tables of a TOML text the bindings do not cover and are passed over: `foreign_section`
// (the [run] table of a spec file), or every section no binding names (the estimator's settings
// read from a window file that records the run's whole config).
struct TomlScope {
  std::string foreign_section;
  bool skip_unbound_sections = false;
};

// Sets the fields of the keys present in a TOML text (`name` in messages) and records their
// origins; throws InputError(name, line, what) on syntax errors, unknown keys, wrong types and
// values outside their key's range.
void applyToml(const Bindings& bindings, const std::string& text, const std::string& name,
               const TomlScope& scope, ConfigOrigins* origins);
// One key from the command line, "section.key=value" (`--set`, a sweep group's `set`), parsed and
// range-checked as its TOML line would be (a name may omit the quotes); its origin becomes
// `option`. Throws UsageError naming the option, the key and what was expected.
void applyAssignment(const Bindings& bindings, const std::string& assignment,
                     const std::string& option, ConfigOrigins* origins);
// Every bound key with its value, one table per section.
std::string bindingsToToml(const Bindings& bindings);
// Every value outside its key's range.
std::vector<ConfigProblem> rangeProblems(const Bindings& bindings);
// A command-line value for `key` (a number or a name) checked against the key's range or names:
// "" when accepted, else the reason. Throws std::logic_error for an unknown key.
std::string checkBindingText(const Bindings& bindings, const std::string& key,
                             const std::string& text);
// The key a relation's message is about: `preferred`, unless only another of `keys` was set.
std::string relationKey(const ConfigOrigins& origins, const std::string& preferred,
                        const std::vector<std::string>& keys);
// A problem with where its value came from: the command-line option (a usage error naming it),
// else the TOML file and line (file "config", line 0, for a default or a value set in code); a
// relation's message names every key involved with its origin.
Problem locateProblem(const ConfigProblem& problem, const ConfigOrigins& origins);

}  // namespace marglab
