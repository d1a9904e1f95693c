#include "core/pipeline/run_spec.h"

#include <fmt/core.h>
#include <toml++/toml.h>

#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <sstream>

#include "core/common/error.h"
#include "core/io/text_input.h"

namespace marglab {
namespace {

// TOML integers are signed 64-bit: a larger seed is written as a string.
void insertSeed(toml::table* run, std::uint64_t seed) {
  if (seed <= static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
    run->insert("seed", static_cast<std::int64_t>(seed));
  } else {
    run->insert("seed", std::to_string(seed));
  }
}

template <typename T>
toml::array arrayOf(const std::vector<T>& values) {
  toml::array array;
  for (const T& v : values) array.push_back(v);
  return array;
}

// Reads the [run] table key by key; every error names the spec file and the key's line.
class RunTableReader {
 public:
  RunTableReader(std::string name, RunSpec* spec) : name_(std::move(name)), spec_(spec) {}

  void read(const toml::table& run) {
    const std::map<std::string, std::function<void(const toml::node&)>> keys = handlers();
    for (const auto& [key, node] : run) {
      const auto it = keys.find(std::string(key.str()));
      if (it == keys.end()) {
        throw error(node, fmt::format("unknown key run.{} (expected one of: dataset, variant, "
                                      "seed, frames, mode, imu, frontend, tracks, "
                                      "tracks_any_sequence, isa, set, output, dump_windows, "
                                      "dump_dir, inject_nan_frame)",
                                      key.str()));
      }
      it->second(node);
    }
    if (spec_->dataset.empty()) throw InputError(name_, 0, "[run] needs a dataset");
  }

 private:
  std::map<std::string, std::function<void(const toml::node&)>> handlers() {
    RunSpec& s = *spec_;
    return {
        {"dataset", [&](const toml::node& n) { s.dataset = text(n, "dataset"); }},
        {"variant", [&](const toml::node& n) { s.variant = variant(n); }},
        {"seed", [&](const toml::node& n) { s.seed = seed(n); }},
        {"frames", [&](const toml::node& n) { s.max_frames = integer(n, "frames", 0); }},
        {"mode", [&](const toml::node& n) { s.mode = choice(n, "mode", kRunModeNames); }},
        {"imu", [&](const toml::node& n) { s.imu = choice(n, "imu", kImuSourceNames); }},
        {"frontend",
         [&](const toml::node& n) { s.frontend = choice(n, "frontend", kFrontendKindNames); }},
        {"tracks", [&](const toml::node& n) { s.tracks_file = text(n, "tracks"); }},
        {"tracks_any_sequence",
         [&](const toml::node& n) { s.tracks_any_sequence = flag(n, "tracks_any_sequence"); }},
        {"isa", [&](const toml::node& n) { s.isa = text(n, "isa"); }},
        {"set", [&](const toml::node& n) { s.overrides = texts(n, "set"); }},
        {"output", [&](const toml::node& n) { s.output = text(n, "output"); }},
        {"dump_windows",
         [&](const toml::node& n) { s.dump_windows = integers(n, "dump_windows"); }},
        {"dump_dir", [&](const toml::node& n) { s.dump_dir = text(n, "dump_dir"); }},
        {"inject_nan_frame",
         [&](const toml::node& n) { s.inject_nan_frame = integer(n, "inject_nan_frame", -1); }},
    };
  }

  InputError error(const toml::node& node, const std::string& what) const {
    return InputError(name_, static_cast<int>(node.source().begin.line), what);
  }
  std::string text(const toml::node& node, const char* key) const {
    const auto v = node.value_exact<std::string>();
    if (!v) throw error(node, fmt::format("expected a string for run.{}", key));
    return *v;
  }
  bool flag(const toml::node& node, const char* key) const {
    const auto v = node.value_exact<bool>();
    if (!v) throw error(node, fmt::format("expected true or false for run.{}", key));
    return *v;
  }
  int integer(const toml::node& node, const char* key, std::int64_t lo) const {
    const auto v = node.value_exact<std::int64_t>();
    if (!v || *v < lo || *v > std::numeric_limits<int>::max()) {
      throw error(node, fmt::format("expected an integer in [{}, {}] for run.{}", lo,
                                    std::numeric_limits<int>::max(), key));
    }
    return static_cast<int>(*v);
  }
  std::uint64_t seed(const toml::node& node) const {
    if (const auto v = node.value_exact<std::int64_t>(); v && *v >= 0) {
      return static_cast<std::uint64_t>(*v);
    }
    const auto s = node.value_exact<std::string>();
    std::size_t used = 0;
    try {
      if (s && !s->empty() && s->front() != '-') {
        const unsigned long long value = std::stoull(*s, &used);
        if (used == s->size()) return value;
      }
    } catch (const std::exception&) {
    }
    throw error(node,
                "expected an integer in [0, 2^64 - 1] for run.seed (a string above 2^63 - 1)");
  }
  Variant variant(const toml::node& node) const {
    try {
      return Variant::parse(text(node, "variant"));
    } catch (const UsageError& e) {
      throw error(node, e.what());
    }
  }
  template <typename E, std::size_t N>
  E choice(const toml::node& node, const char* key, const EnumNames<E, N>& names) const {
    E value{};
    if (!parseName(names, text(node, key), &value)) {
      throw error(node, fmt::format("expected {} for run.{}", describeNames(names), key));
    }
    return value;
  }
  std::vector<std::string> texts(const toml::node& node, const char* key) const {
    const toml::array* array = node.as_array();
    if (array == nullptr)
      throw error(node, fmt::format("expected a list of strings for run.{}", key));
    std::vector<std::string> out;
    for (const toml::node& item : *array) out.push_back(text(item, key));
    return out;
  }
  std::vector<int> integers(const toml::node& node, const char* key) const {
    const toml::array* array = node.as_array();
    if (array == nullptr)
      throw error(node, fmt::format("expected a list of integers for run.{}", key));
    std::vector<int> out;
    for (const toml::node& item : *array) out.push_back(integer(item, key, 0));
    return out;
  }

  std::string name_;
  RunSpec* spec_;
};

}  // namespace

std::string RunSpec::toToml() const {
  toml::table run;
  run.insert("dataset", dataset);
  run.insert("variant", variant.name());
  insertSeed(&run, seed);
  run.insert("frames", max_frames);
  run.insert("mode", nameOf(kRunModeNames, mode));
  run.insert("imu", nameOf(kImuSourceNames, imu));
  run.insert("frontend", nameOf(kFrontendKindNames, frontend));
  run.insert("tracks", tracks_file);
  run.insert("tracks_any_sequence", tracks_any_sequence);
  run.insert("isa", isa);
  run.insert("set", arrayOf(overrides));
  run.insert("output", output);
  run.insert("dump_windows", arrayOf(dump_windows));
  run.insert("dump_dir", dump_dir);
  if (inject_nan_frame >= 0) run.insert("inject_nan_frame", inject_nan_frame);
  toml::table root;
  root.insert("run", std::move(run));
  std::ostringstream out;
  out << "# marglab run spec (core/pipeline/run_spec.h): `marglab run --spec FILE` repeats it\n"
      << root << "\n\n"
      << config.toToml() << "\n";
  return out.str();
}

RunSpec RunSpec::fromTomlString(const std::string& text, const std::string& name) {
  RunSpec spec;
  toml::table root;
  try {
    root = toml::parse(text, name);
  } catch (const toml::parse_error& e) {
    throw InputError(name, static_cast<int>(e.source().begin.line), std::string(e.description()));
  }
  const toml::table* run = root["run"].as_table();
  if (run == nullptr) throw InputError(name, 0, "expected a [run] table (a run spec file)");
  RunTableReader(name, &spec).read(*run);
  spec.config.loadTomlString(text, name, "run");
  return spec;
}

RunSpec RunSpec::fromTomlFile(const std::string& path) {
  return fromTomlString(readTextInput(path, "the run spec file", kSettingsTextLimits), path);
}

}  // namespace marglab
