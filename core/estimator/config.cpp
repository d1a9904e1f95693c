#include "core/estimator/config.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <toml++/toml.h>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "core/common/error.h"
#include "core/io/text_input.h"

namespace marglab {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The accepted values of a numeric key: a finite number in [lo, hi] (either end open or
// unbounded), or exactly `sentinel` (e.g. −1 for "dataset default").
struct Rule {
  double lo = -kInf;
  double hi = kInf;
  bool lo_open = false;
  bool hi_open = false;
  bool has_sentinel = false;
  double sentinel = 0;
  const char* sentinel_meaning = nullptr;
};

Rule atLeast(double lo) { return Rule{lo}; }
Rule above(double lo) { return Rule{lo, kInf, true}; }
Rule between(double lo, double hi) { return Rule{lo, hi}; }
Rule orSentinel(Rule rule, double sentinel, const char* meaning) {
  rule.has_sentinel = true;
  rule.sentinel = sentinel;
  rule.sentinel_meaning = meaning;
  return rule;
}

bool accepts(const Rule& rule, double v) {
  if (rule.has_sentinel && v == rule.sentinel) return true;
  if (!std::isfinite(v)) return false;
  if (rule.lo_open ? v <= rule.lo : v < rule.lo) return false;
  if (rule.hi_open ? v >= rule.hi : v > rule.hi) return false;
  return true;
}

std::string number(double v, bool integer) {
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
    text = fmt::format("{} in {}{}, {}{}", kind, rule.lo_open ? "(" : "[", number(rule.lo, integer),
                       number(rule.hi, integer), rule.hi_open ? ")" : "]");
  } else if (std::isfinite(rule.lo)) {
    text = fmt::format("{} {} {}", kind, rule.lo_open ? ">" : ">=", number(rule.lo, integer));
  } else if (std::isfinite(rule.hi)) {
    text = fmt::format("{} {} {}", kind, rule.hi_open ? "<" : "<=", number(rule.hi, integer));
  } else {
    text = kind;
  }
  if (rule.has_sentinel) {
    text =
        fmt::format("{} ({}) or {}", number(rule.sentinel, integer), rule.sentinel_meaning, text);
  }
  return text;
}

// One TOML key bound to a config field.
struct Binding {
  const char* section;
  const char* key;
  double* d = nullptr;
  int* i = nullptr;
  bool* b = nullptr;
  std::uint64_t* u = nullptr;
  std::vector<double>* list = nullptr;  // a list of numbers, each in `rule`
  Rule rule = Rule{};  // numeric keys (d, i, u) and the elements of a list
  // A key with a fixed set of names (an enum field): parse (false for an unknown name), print.
  std::function<bool(const std::string&)> parse_choice = nullptr;
  std::function<std::string()> print_choice = nullptr;
  std::string choices = "";  // for messages: "\"a\" or \"b\""

  std::string name() const { return std::string(section) + "." + key; }
  bool numeric() const { return d != nullptr || i != nullptr || u != nullptr; }
  bool integer() const { return i != nullptr || u != nullptr; }
  double value() const { return d != nullptr ? *d : i != nullptr ? *i : static_cast<double>(*u); }
  // "lm.threads = 0: expected an integer in [1, 256]"
  std::string problem(double v) const {
    return fmt::format("{} = {}: expected {}", name(), number(v, integer()),
                       describe(rule, integer()));
  }
};

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

// The [frontend] keys (core/frontend/frontend_options.h). The ranges keep OpenCV's LK and
// corner detector inside what they accept (a window of at least 5 px, a block of at least 2) and
// the checks meaningful (an NCC bound in [−1, 1], a sine bound in (0, 1]).
template <typename AddDouble, typename AddInt>
void frontendBindings(FrontendOptions& f, AddDouble D, AddInt I, std::vector<Binding>* list) {
  const char* s = "frontend";
  I(s, "grid_cell_px", &f.grid_cell_px, orSentinel(between(8, 10000), -1, "dataset default"));
  I(s, "pyramid_levels", &f.pyramid_levels, orSentinel(between(1, 8), -1, "dataset default"));
  I(s, "max_iterations", &f.max_iterations, between(1, 100));
  I(s, "window_px", &f.window_px, between(5, 101));
  D(s, "fb_max_px", &f.fb_max_px, above(0));
  D(s, "epipolar_max", &f.epipolar_max, Rule{0, 1, true});
  D(s, "ncc_min", &f.ncc_min, between(-1, 1));
  D(s, "ransac_px", &f.ransac_px, above(0));
  D(s, "min_eigen", &f.min_eigen, atLeast(0));
  I(s, "corner_block_px", &f.corner_block_px, between(2, 31));
  I(s, "border_px", &f.border_px, between(0, 10000));
  I(s, "detect_margin_px", &f.detect_margin_px,
    orSentinel(between(0, 10000), -1, "dataset default"));
  Binding guesses{s, "disparity_guesses_px"};
  guesses.list = &f.disparity_guesses_px;
  guesses.rule = between(0, 10000);
  list->push_back(guesses);
  list->push_back(choice(s, "prediction", &f.prediction, kMotionPredictionSourceNames));
}

// The keys and their ranges (docs/design.md §9). The ranges follow what the estimator does with
// each value: e.g. max_kfs = 0 ended the run in "map::at", λ = 0 never grows (λ ← λν), a zero σ
// makes the cost non-finite, max_iterations = 0 skips the optimization, and the estimator silently
// raised max_states < 2 to 2. Upper bounds keep integers from overflowing and the window sane.
std::vector<Binding> bindings(EstimatorConfig& c) {
  std::vector<Binding> list;
  auto D = [&](const char* s, const char* k, double* v, Rule rule) {
    Binding binding{s, k, v};
    binding.rule = rule;
    list.push_back(binding);
  };
  auto I = [&](const char* s, const char* k, int* v, Rule rule) {
    Binding binding{s, k, nullptr, v};
    binding.rule = rule;
    list.push_back(binding);
  };
  constexpr double kMaxWindow = 1000000;
  D("residuals", "obs_std_px", &c.obs_std_px, above(0));
  I("window", "max_kfs", &c.max_kfs, between(1, kMaxWindow));
  I("window", "max_states", &c.max_states, between(2, kMaxWindow));
  D("residuals", "huber_px", &c.huber_px, above(0));
  D("gauge", "prior_weight", &c.gauge_prior_weight, atLeast(0));
  D("gauge", "prior_bias_gyro", &c.gauge_prior_bias_gyro, atLeast(0));
  D("gauge", "prior_bias_accel", &c.gauge_prior_bias_accel, atLeast(0));
  D("keyframes", "connected_ratio", &c.kf_connected_ratio, Rule{0, 1, true});
  I("keyframes", "min_frames_after_kf", &c.min_frames_after_kf,
    orSentinel(between(1, kMaxWindow), -1, "dataset default"));
  D("keyframes", "min_baseline_m", &c.min_baseline_m, atLeast(0));
  D("keyframes", "marg_connected_share", &c.marg_connected_share, between(0, 1));
  I("lm", "max_iterations", &c.lm_max_iterations, between(1, 1000));
  D("lm", "lambda_init", &c.lambda_init, above(0));
  D("lm", "lambda_min", &c.lambda_min, above(0));
  D("lm", "lambda_max", &c.lambda_max, above(0));
  D("lm", "stop_relative_cost", &c.stop_relative_cost, atLeast(0));
  D("lm", "stop_max_step", &c.stop_max_step, atLeast(0));
  list.push_back(choice("lm", "stop_rule", &c.lm_stop_rule, kLmStopRuleNames));
  I("lm", "max_failed_solves", &c.max_failed_solves, between(1, 1000));
  list.push_back({"lm", "landmark_damping", nullptr, nullptr, &c.lm_landmark_damping});
  I("lm", "threads", &c.lm_threads, between(1, kMaxLmThreads));
  list.push_back(choice("marginalization", "qr_threshold_mode", &c.qr_threshold_mode,
                        kRankThresholdModeNames));
  D("marginalization", "qr_threshold", &c.qr_threshold,
    orSentinel(atLeast(0), -1, "sqrt(eps) of the precision"));
  list.push_back(choice("marginalization", "strategy", &c.marg_strategy, kMargStrategyNames));
  list.push_back(
      choice("marginalization", "nfr_topology", &c.nfr_topology, kSparsifyTopologyNames));
  list.push_back(
      {"marginalization", "nfr_rigid_deflation", nullptr, nullptr, &c.nfr_rigid_deflation});
  list.push_back({"marginalization", "psd_hessian_prior", nullptr, nullptr, &c.psd_hessian_prior});
  frontendBindings(c.frontend, D, I, &list);
  D("failure", "max_position_error_m", &c.max_position_error_m,
    orSentinel(above(0), -1, "dataset default"));
  I("failure", "min_tracked_observations", &c.min_tracked_observations, between(0, 100000));
  I("failure", "max_tracking_loss_frames", &c.max_tracking_loss_frames, between(1, kMaxWindow));
  D("failure", "inconsistent_px", &c.inconsistent_px, above(0));
  D("failure", "max_inconsistent_share", &c.max_inconsistent_share, between(0, 1));
  list.push_back(choice("imu", "noise_profile", &c.imu_noise_profile, kImuNoiseProfileNames));
  list.push_back(choice("sim", "profile", &c.sim_profile, kSimProfileNames));
  list.push_back({"diagnostics", "enabled", nullptr, nullptr, &c.diagnostics});
  I("diagnostics", "store_prior_every", &c.store_prior_every,
    between(0, std::numeric_limits<int>::max()));
  Binding seed{"diagnostics", "seed", nullptr, nullptr, nullptr, &c.diagnostics_seed};
  seed.rule = atLeast(0);  // and a TOML integer, i.e. at most 2^63 − 1
  list.push_back(seed);
  return list;
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

void apply(EstimatorConfig& config, const toml::table& root, const std::string& name,
           const std::string& foreign_section) {
  auto list = bindings(config);
  auto error = [&](const toml::node& node, const std::string& what) {
    return InputError(name, static_cast<int>(node.source().begin.line), what);
  };
  for (const auto& [section_key, section_node] : root) {
    const std::string section(section_key.str());
    if (section == foreign_section) continue;
    const toml::table* table = section_node.as_table();
    if (table == nullptr) throw error(section_node, "expected a table [" + section + "]");
    for (const auto& [key_key, node] : *table) {
      const std::string key(key_key.str());
      auto it = std::find_if(list.begin(), list.end(), [&](const Binding& b) {
        return section == b.section && key == b.key;
      });
      if (it == list.end()) throw error(node, fmt::format("unknown key {}.{}", section, key));
      if (it->d != nullptr) {
        auto v = node.value<double>();
        if (!v) throw error(node, fmt::format("expected a number for {}.{}", section, key));
        if (!accepts(it->rule, *v)) throw error(node, it->problem(*v));
        *it->d = *v;
      } else if (it->integer()) {
        bool out_of_range = false;
        const auto v = integerValue(node, &out_of_range);
        if (out_of_range) {
          throw error(node, fmt::format("{} = {}: expected {}", it->name(), *node.value<double>(),
                                        describe(it->rule, true)));
        }
        if (!v) {
          throw error(node,
                      fmt::format("expected {} for {}", describe(it->rule, true), it->name()));
        }
        // Checked as int64, before narrowing: a value outside the range never wraps.
        if (!accepts(it->rule, static_cast<double>(*v))) {
          throw error(
              node, fmt::format("{} = {}: expected {}", it->name(), *v, describe(it->rule, true)));
        }
        if (it->i != nullptr) {
          *it->i = static_cast<int>(*v);
        } else {
          *it->u = static_cast<std::uint64_t>(*v);
        }
      } else if (it->list != nullptr) {
        *it->list = numberList(*it, node, error);
      } else if (it->b != nullptr) {
        auto v = node.value<bool>();
        if (!v) throw error(node, fmt::format("expected true or false for {}.{}", section, key));
        *it->b = *v;
      } else {
        auto v = node.value<std::string>();
        if (!v || !it->parse_choice(*v)) {
          throw error(node, fmt::format("expected {} for {}.{}", it->choices, section, key));
        }
      }
      config.origins[it->name()] =
          ConfigOrigin{name, static_cast<int>(node.source().begin.line), ""};
    }
  }
}

}  // namespace

namespace {

bool isToml(const std::string& text) {
  try {
    static_cast<void>(toml::parse(text));
    return true;
  } catch (const toml::parse_error&) {
    return false;
  }
}

}  // namespace

void EstimatorConfig::loadTomlString(const std::string& text, const std::string& name,
                                     const std::string& foreign_section) {
  try {
    apply(*this, toml::parse(text, name), name, foreign_section);
  } catch (const toml::parse_error& e) {
    throw InputError(name, static_cast<int>(e.source().begin.line), std::string(e.description()));
  }
}

void EstimatorConfig::set(const std::string& assignment, const std::string& option) {
  const std::size_t eq = assignment.find('=');
  const std::string key = assignment.substr(0, eq);
  const std::size_t dot = key.find('.');
  const auto name_char = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
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
    loadTomlString(text, "--set");
  } catch (const InputError& e) {
    throw UsageError(fmt::format("{} {}: {}", option, shortToken(assignment), e.detail()));
  }
  setOrigin(key, option);
}

void EstimatorConfig::loadToml(const std::string& path) {
  loadTomlString(readTextInput(path, "the config file", kSettingsTextLimits), path);
}

std::string EstimatorConfig::toToml() const {
  EstimatorConfig copy = *this;
  toml::table root;
  for (const Binding& b : bindings(copy)) {
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

std::string ConfigOrigin::describe() const {
  if (!option.empty()) return option;
  if (file.empty()) return "";
  return line > 0 ? fmt::format("{}:{}", file, line) : file;
}

void EstimatorConfig::setOrigin(const std::string& key, const std::string& option) {
  origins[key] = ConfigOrigin{"", 0, option};
}

std::vector<ConfigProblem> EstimatorConfig::problems() const {
  EstimatorConfig copy = *this;
  std::vector<ConfigProblem> out;
  for (const Binding& b : bindings(copy)) {
    if (b.numeric() && !accepts(b.rule, b.value())) out.push_back({b.name(), b.problem(b.value())});
    if (b.list != nullptr) {
      for (const double v : *b.list) {
        if (!accepts(b.rule, v)) {
          out.push_back({b.name(), fmt::format("{} holds {}: expected numbers that are each {}",
                                               b.name(), v, describe(b.rule, false))});
          break;
        }
      }
    }
  }
  // Relations between keys, when each key is valid on its own.
  auto valid = [&out](const char* key) {
    return std::none_of(out.begin(), out.end(),
                        [key](const ConfigProblem& p) { return p.key == key; });
  };
  // The key a relation's message is about: `preferred`, unless only another one was set.
  auto pick = [this](const std::string& preferred, std::initializer_list<const char*> keys) {
    if (origins.count(preferred) != 0) return preferred;
    for (const char* k : keys) {
      if (origins.count(k) != 0) return std::string(k);
    }
    return preferred;
  };
  if (valid("lm.lambda_min") && valid("lm.lambda_init") && valid("lm.lambda_max") &&
      !(lambda_min <= lambda_init && lambda_init <= lambda_max)) {
    const std::initializer_list<const char*> keys = {"lm.lambda_min", "lm.lambda_init",
                                                     "lm.lambda_max"};
    out.push_back({pick(lambda_min > lambda_max ? "lm.lambda_min" : "lm.lambda_init", keys),
                   fmt::format("lm.lambda_min = {}, lm.lambda_init = {}, lm.lambda_max = {}: "
                               "expected lambda_min <= lambda_init <= lambda_max",
                               lambda_min, lambda_init, lambda_max),
                   {keys.begin(), keys.end()}});
  }
  if (valid("marginalization.qr_threshold") && qr_threshold_mode == RankThresholdMode::kRelative &&
      qr_threshold >= 1) {
    const std::initializer_list<const char*> keys = {"marginalization.qr_threshold",
                                                     "marginalization.qr_threshold_mode"};
    out.push_back({pick("marginalization.qr_threshold", keys),
                   fmt::format("marginalization.qr_threshold = {} with qr_threshold_mode = "
                               "\"relative\": expected a relative threshold in [0, 1) (a column "
                               "counts as dependent when its remaining norm is at most the "
                               "threshold times its norm, so 1 or more drops every column)",
                               qr_threshold),
                   {keys.begin(), keys.end()}});
  }
  if (nfr_rigid_deflation &&
      (marg_strategy != MargStrategy::kNfr || nfr_topology != SparsifyTopology::kPaper)) {
    const std::initializer_list<const char*> keys = {"marginalization.nfr_rigid_deflation",
                                                     "marginalization.strategy",
                                                     "marginalization.nfr_topology"};
    out.push_back({pick("marginalization.nfr_rigid_deflation", keys),
                   fmt::format("marginalization.nfr_rigid_deflation = true with strategy = \"{}\" "
                               "and nfr_topology = \"{}\": expected strategy \"nfr\" with "
                               "nfr_topology \"paper\" (the deflation acts on unary factors on "
                               "every pose of the blanket)",
                               toString(marg_strategy), toString(nfr_topology)),
                   {keys.begin(), keys.end()}});
  }
  return out;
}

Problem EstimatorConfig::located(const ConfigProblem& p) const {
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

std::vector<Problem> EstimatorConfig::locatedProblems() const {
  std::vector<Problem> out;
  for (const ConfigProblem& p : problems()) out.push_back(located(p));
  return out;
}

void EstimatorConfig::validate() const {
  const std::vector<Problem> list = locatedProblems();
  if (!list.empty()) throwProblems(list);
}

std::string EstimatorConfig::checkValueText(const std::string& key, const std::string& text) {
  EstimatorConfig probe;
  for (const Binding& b : bindings(probe)) {
    if (b.name() != key) continue;
    if (b.parse_choice) {
      return b.parse_choice(text) ? std::string()
                                  : fmt::format("{} = {}: expected {}", key, shortToken(text),
                                                b.choices);
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

}  // namespace marglab
