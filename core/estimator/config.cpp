#include "core/estimator/config.h"

#include <fmt/core.h>

#include <toml++/toml.h>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <limits>
#include <sstream>

#include "core/common/error.h"

namespace marglab {
namespace {

// One TOML key bound to a config field.
struct Binding {
  const char* section;
  const char* key;
  double* d = nullptr;
  int* i = nullptr;
  bool* b = nullptr;
  std::uint64_t* u = nullptr;
  int min_i = std::numeric_limits<int>::min();  // smallest accepted value of an int key
  // A key with a fixed set of names (an enum field): parse (false for an unknown name), print.
  std::function<bool(const std::string&)> parse_choice = nullptr;
  std::function<std::string()> print_choice = nullptr;
  const char* choices = nullptr;  // for messages: "\"a\" or \"b\""
};

// Binds an enum field with toString(E) / a parser bool(const std::string&, E*).
template <typename E, typename Parse>
Binding choice(const char* section, const char* key, E* field, Parse parse, const char* choices) {
  Binding binding{section, key};
  binding.parse_choice = [field, parse](const std::string& text) { return parse(text, field); };
  binding.print_choice = [field] { return std::string(toString(*field)); };
  binding.choices = choices;
  return binding;
}

std::vector<Binding> bindings(EstimatorConfig& c) {
  std::vector<Binding> list;
  auto D = [&](const char* s, const char* k, double* v) { list.push_back({s, k, v}); };
  auto I = [&](const char* s, const char* k, int* v, int min = std::numeric_limits<int>::min()) {
    Binding binding{s, k, nullptr, v};
    binding.min_i = min;
    list.push_back(binding);
  };
  D("residuals", "obs_std_px", &c.obs_std_px);
  I("window", "max_kfs", &c.max_kfs);
  I("window", "max_states", &c.max_states);
  D("residuals", "huber_px", &c.huber_px);
  D("gauge", "prior_weight", &c.gauge_prior_weight);
  D("gauge", "prior_bias_gyro", &c.gauge_prior_bias_gyro);
  D("gauge", "prior_bias_accel", &c.gauge_prior_bias_accel);
  D("keyframes", "connected_ratio", &c.kf_connected_ratio);
  I("keyframes", "min_frames_after_kf", &c.min_frames_after_kf);
  D("keyframes", "min_baseline_m", &c.min_baseline_m);
  D("keyframes", "marg_connected_share", &c.marg_connected_share);
  I("lm", "max_iterations", &c.lm_max_iterations);
  D("lm", "lambda_init", &c.lambda_init);
  D("lm", "lambda_min", &c.lambda_min);
  D("lm", "lambda_max", &c.lambda_max);
  D("lm", "stop_relative_cost", &c.stop_relative_cost);
  D("lm", "stop_max_step", &c.stop_max_step);
  I("lm", "max_failed_solves", &c.max_failed_solves);
  list.push_back({"lm", "landmark_damping", nullptr, nullptr, &c.lm_landmark_damping});
  I("lm", "threads", &c.lm_threads, 1);
  list.push_back(choice("marginalization", "qr_threshold_mode", &c.qr_threshold_mode,
                        parseRankThresholdMode, "\"absolute\" or \"relative\""));
  D("marginalization", "qr_threshold", &c.qr_threshold);
  list.push_back(choice("marginalization", "strategy", &c.marg_strategy, parseMargStrategy,
                        "\"discard\", \"dense\" or \"nfr\""));
  list.push_back(choice("marginalization", "nfr_topology", &c.nfr_topology, parseSparsifyTopology,
                        "\"paper\" or \"joint-states\""));
  D("failure", "max_position_error_m", &c.max_position_error_m);
  list.push_back({"diagnostics", "enabled", nullptr, nullptr, &c.diagnostics});
  I("diagnostics", "store_prior_every", &c.store_prior_every);
  list.push_back({"diagnostics", "seed", nullptr, nullptr, nullptr, &c.diagnostics_seed});
  return list;
}

void apply(EstimatorConfig& config, const toml::table& root, const std::string& name) {
  auto list = bindings(config);
  auto error = [&](const toml::node& node, const std::string& what) {
    return InputError(name, static_cast<int>(node.source().begin.line), what);
  };
  for (const auto& [section_key, section_node] : root) {
    const std::string section(section_key.str());
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
        *it->d = *v;
      } else if (it->i != nullptr) {
        auto v = node.value<int64_t>();
        if (!v) throw error(node, fmt::format("expected an integer for {}.{}", section, key));
        if (*v < it->min_i) {
          throw error(node, fmt::format("expected {}.{} >= {}", section, key, it->min_i));
        }
        *it->i = static_cast<int>(*v);
      } else if (it->b != nullptr) {
        auto v = node.value<bool>();
        if (!v) throw error(node, fmt::format("expected true or false for {}.{}", section, key));
        *it->b = *v;
      } else if (it->u != nullptr) {
        auto v = node.value<int64_t>();
        if (!v || *v < 0) {
          throw error(node, fmt::format("expected a non-negative integer for {}.{}", section, key));
        }
        *it->u = static_cast<std::uint64_t>(*v);
      } else {
        auto v = node.value<std::string>();
        if (!v || !it->parse_choice(*v)) {
          throw error(node, fmt::format("expected {} for {}.{}", it->choices, section, key));
        }
      }
    }
  }
}

// The value among `values` whose toString() is text.
template <typename E>
bool parseByName(const std::string& text, std::initializer_list<E> values, E* out) {
  for (E value : values) {
    if (text == toString(value)) {
      *out = value;
      return true;
    }
  }
  return false;
}

}  // namespace

const char* toString(MargStrategy strategy) {
  switch (strategy) {
    case MargStrategy::kDense:
      return "dense";
    case MargStrategy::kNfr:
      return "nfr";
    case MargStrategy::kDiscard:
      break;
  }
  return "discard";
}

const char* toString(SparsifyTopology topology) {
  return topology == SparsifyTopology::kJointStates ? "joint-states" : "paper";
}

bool parseSparsifyTopology(const std::string& text, SparsifyTopology* topology) {
  return parseByName(text, {SparsifyTopology::kPaper, SparsifyTopology::kJointStates}, topology);
}

bool parseMargStrategy(const std::string& text, MargStrategy* strategy) {
  return parseByName(text, {MargStrategy::kDiscard, MargStrategy::kDense, MargStrategy::kNfr},
                     strategy);
}

void EstimatorConfig::loadTomlString(const std::string& text, const std::string& name) {
  try {
    apply(*this, toml::parse(text, name), name);
  } catch (const toml::parse_error& e) {
    throw InputError(name, static_cast<int>(e.source().begin.line), std::string(e.description()));
  }
}

void EstimatorConfig::loadToml(const std::string& path) {
  std::ifstream file(path);
  if (!file) throw InputError(path, 0, "cannot open the config file");
  std::stringstream buffer;
  buffer << file.rdbuf();
  loadTomlString(buffer.str(), path);
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
    } else {
      section.insert(b.key, b.print_choice());
    }
  }
  std::ostringstream out;
  out << root;
  return out.str();
}

}  // namespace marglab
