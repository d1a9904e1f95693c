#include "core/experiment/sweep_def.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <toml++/toml.h>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/ba/bal_problem.h"
#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/estimator/variant.h"
#include "core/io/text_input.h"
#include "core/pipeline/run_config.h"

namespace marglab::experiment {
namespace {

namespace fs = std::filesystem;

int lineOf(const toml::node& node) { return static_cast<int>(node.source().begin.line); }

// Options `marglab sweep` sets itself for every run.
const char* const kReservedRunOptions[] = {"--dataset", "--variant", "--frames", "--seed",
                                           "--config",  "-o",        "--output", "--spec"};

bool validName(const std::string& name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
  });
}

// The text after "FILE:LINE: " of an InputError made for an in-memory string named `name`.
std::string stripLocation(const InputError& e) {
  const std::string what = e.what();
  std::string prefix = e.file() + ":";
  if (e.line() > 0) prefix += std::to_string(e.line()) + ":";
  prefix += " ";
  return what.rfind(prefix, 0) == 0 ? what.substr(prefix.size()) : what;
}

void mergeInto(toml::table& dst, const toml::table& src) {
  for (const auto& [key, node] : src) {
    toml::table* dst_table = dst[key].as_table();
    const toml::table* src_table = node.as_table();
    if (dst_table != nullptr && src_table != nullptr) {
      mergeInto(*dst_table, *src_table);
    } else {
      node.visit([&, k = key](const auto& value) { dst.insert_or_assign(k, value); });
    }
  }
}

std::string toTomlText(const toml::table& table) {
  if (table.empty()) return {};
  std::ostringstream os;
  os << table << "\n";
  return os.str();
}

class Parser {
 public:
  Parser(std::string name, std::string base_dir, const ParseOptions& options)
      : name_(std::move(name)), base_dir_(std::move(base_dir)), options_(options) {
    sequences_ = options.known_sequences_given ? options.known_sequences : listSequences();
  }

  SweepPlan parse(const std::string& text) {
    toml::table root;
    try {
      root = toml::parse(text, name_);
    } catch (const toml::parse_error& e) {
      throw InputError(name_, lineOf0(e.source()), std::string(e.description()));
    }
    SweepPlan plan;
    plan.source_file = name_;
    checkKeys(root, {"name", "description", "group"}, "the sweep");
    plan.name = requiredString(root, "name", "the sweep", 1);
    if (!validName(plan.name)) {
      throw error(*root.get("name"), "name must use only letters, digits, '_', '-', '.'");
    }
    plan.description = optionalString(root, "description").value_or("");
    const toml::node* groups = root.get("group");
    if (groups == nullptr) throw InputError(name_, 0, "no [[group]]: the sweep has no runs");
    const toml::array* array = groups->as_array();
    if (array == nullptr || !array->is_array_of_tables() || array->empty()) {
      throw error(*groups, "group must be an array of tables ([[group]])");
    }
    std::set<std::string> group_names;
    for (const toml::node& node : *array) {
      const toml::table& group = *node.as_table();
      if (isBaGroup(group)) {
        parseBaGroup(group, &plan);
      } else {
        parseGroup(group, &plan);
      }
      if (!group_names.insert(plan.runs.empty() ? "" : plan.runs.back().group).second) {
        throw error(*group.get("name"), "duplicate group name '" + plan.runs.back().group + "'");
      }
    }
    return plan;
  }

 private:
  static int lineOf0(const toml::source_region& region) {
    return static_cast<int>(region.begin.line);
  }

  InputError error(const toml::node& node, const std::string& what) const {
    return InputError(name_, lineOf(node), what);
  }

  void checkKeys(const toml::table& table, std::initializer_list<const char*> allowed,
                 const std::string& where) const {
    for (const auto& [key, node] : table) {
      const std::string k(key.str());
      if (std::none_of(allowed.begin(), allowed.end(), [&](const char* a) { return k == a; })) {
        std::vector<std::string> names(allowed.begin(), allowed.end());
        throw InputError(name_, static_cast<int>(key.source().begin.line),
                         fmt::format("unknown key '{}' in {} (expected one of: {})", k, where,
                                     fmt::join(names, ", ")));
      }
    }
  }

  std::string requiredString(const toml::table& table, const char* key, const std::string& where,
                             int line) const {
    const toml::node* node = table.get(key);
    if (node == nullptr) {
      throw InputError(name_, line, fmt::format("{} needs a {} = \"...\"", where, key));
    }
    if (!node->is_string()) throw error(*node, fmt::format("{} must be a string", key));
    return **node->as_string();
  }

  std::optional<std::string> optionalString(const toml::table& table, const char* key) const {
    const toml::node* node = table.get(key);
    if (node == nullptr) return std::nullopt;
    if (!node->is_string()) throw error(*node, fmt::format("{} must be a string", key));
    return **node->as_string();
  }

  std::vector<const toml::node*> nonEmptyArray(const toml::table& table, const char* key,
                                               const std::string& where, int line) const {
    const toml::node* node = table.get(key);
    if (node == nullptr)
      throw InputError(name_, line, fmt::format("{} needs {} = [...]", where, key));
    const toml::array* array = node->as_array();
    if (array == nullptr) throw error(*node, fmt::format("{} must be an array", key));
    if (array->empty()) throw error(*node, fmt::format("{} is empty", key));
    std::vector<const toml::node*> items;
    for (const toml::node& item : *array) items.push_back(&item);
    return items;
  }

  std::vector<std::string> stringArray(const toml::table& table, const char* key) const {
    std::vector<std::string> out;
    const toml::node* node = table.get(key);
    if (node == nullptr) return out;
    const toml::array* array = node->as_array();
    if (array == nullptr) throw error(*node, fmt::format("{} must be an array of strings", key));
    for (const toml::node& item : *array) {
      if (!item.is_string()) throw error(item, fmt::format("{} must hold strings", key));
      out.push_back(**item.as_string());
    }
    return out;
  }

  // The `args` of a group or override: checked for reserved options and by the run checker.
  std::vector<std::string> runArgs(const toml::table& table) const {
    std::vector<std::string> args = stringArray(table, "args");
    if (args.empty()) return args;
    const toml::node& node = *table.get("args");
    for (const std::string& arg : args) {
      const std::string option = arg.substr(0, arg.find('='));
      for (const char* reserved : kReservedRunOptions) {
        if (option == reserved) {
          throw error(node, fmt::format("args: {} is set by the sweep itself (use datasets, "
                                        "variants, frames, seeds or config)",
                                        reserved));
        }
      }
    }
    if (options_.check_run_args) {
      const std::string problem = options_.check_run_args(args);
      if (!problem.empty())
        throw error(node, "args are not valid `marglab run` options: " + problem);
    }
    return args;
  }

  // The `set` of a group or override ("section.key=value", as `marglab run --set`): run options
  // appended to its args, checked at the line of `set`.
  std::vector<std::string> setArgs(const toml::table& table) const {
    std::vector<std::string> args;
    for (const std::string& assignment : stringArray(table, "set")) {
      args.push_back("--set");
      args.push_back(assignment);
    }
    if (args.empty() || !options_.check_run_args) return args;
    const std::string problem = options_.check_run_args(args);
    if (!problem.empty()) throw error(*table.get("set"), "set: " + problem);
    return args;
  }

  // An inline [config] table: validated key by key against RunConfig, so that an error
  // names the line of the offending key.
  toml::table configTable(const toml::table& table) const {
    const toml::node* node = table.get("config");
    if (node == nullptr) return {};
    const toml::table* config = node->as_table();
    if (config == nullptr) throw error(*node, "config must be a table, e.g. [group.config]");
    for (const auto& [section_key, section_node] : *config) {
      const toml::table* section = section_node.as_table();
      if (section == nullptr) {
        throw error(section_node,
                    fmt::format("config.{} must be a table (a config section)", section_key.str()));
      }
      for (const auto& [key, value] : *section) {
        toml::table single;
        toml::table inner;
        value.visit([&, k = key](const auto& v) { inner.insert_or_assign(k, v); });
        single.insert_or_assign(section_key, inner);
        try {
          RunConfig probe;
          probe.loadTomlString(toTomlText(single), "config");
        } catch (const InputError& e) {
          throw error(value, "config: " + stripLocation(e));
        }
      }
    }
    return *config;
  }

  // The merged config of one run (config_file, [group.config], the override): each value was
  // checked against its range where it was read; here the relations between keys
  // (docs/design.md §9), every one reported at the line of the group or override.
  void checkMergedConfig(const std::string& config_toml, int line, const std::string& where) const {
    if (config_toml.empty()) return;
    RunConfig probe;
    probe.loadTomlString(config_toml, "config");
    const std::vector<ConfigProblem> problems = probe.problems();
    if (problems.empty()) return;
    std::string message = where + ": config: " + problems.front().message;
    for (std::size_t i = 1; i < problems.size(); ++i) message += "; also: " + problems[i].message;
    throw InputError(name_, line, message);
  }

  std::string resolveDataset(const toml::node& node) const {
    if (!node.is_string()) throw error(node, "datasets must hold strings");
    const std::string dataset = **node.as_string();
    if (std::find(sequences_.begin(), sequences_.end(), dataset) != sequences_.end()) {
      return dataset;
    }
    fs::path path(dataset);
    if (path.is_relative()) path = fs::path(base_dir_) / path;
    if (fs::is_directory(path)) return normalizeDatasetArgument(fs::absolute(path).string());
    throw error(node, fmt::format("unknown dataset '{}': not a shipped sequence (see `marglab "
                                  "datasets list`) nor a folder",
                                  dataset));
  }

  // The dataset's slug names its runs, logs and track file: two datasets with one slug (folders
  // a/06 and a-06, or names differing only in characters the slug replaces) would share them.
  void checkSlugIsItsOwn(const std::string& dataset, const toml::node& node) {
    const auto [earlier, fresh] =
        dataset_slugs_.emplace(slug(dataset), Listed{dataset, lineOf(node)});
    if (fresh || earlier->second.dataset == dataset) return;
    throw error(
        node, fmt::format("datasets '{}' (line {}) and '{}' have the same slug '{}', which "
                          "names their runs, logs and track files (characters other than "
                          "letters, digits, '_', '.', '-' become '-'): rename or link "
                          "one of the folders",
                          earlier->second.dataset, earlier->second.line, dataset, earlier->first));
  }

  // One [[group]]: its keys in the order they are checked, then its runs (datasets × variants ×
  // seeds × overrides) appended to the plan.
  void parseGroup(const toml::table& group, SweepPlan* plan) {
    GroupSpec g;
    g.line = lineOf(group);
    checkKeys(group,
              {"name", "kind", "datasets", "variants", "seeds", "frames", "timeout_s", "args",
               "set", "frontend", "config_file", "config", "override"},
              "a [[group]]");
    g.name = requiredString(group, "name", "a [[group]]", g.line);
    if (!validName(g.name)) {
      throw error(*group.get("name"), "group name must use only letters, digits, '_', '-', '.'");
    }
    for (const toml::node* node : nonEmptyArray(group, "datasets", "a [[group]]", g.line)) {
      g.datasets.push_back(resolveDataset(*node));
      checkSlugIsItsOwn(g.datasets.back(), *node);
    }
    g.variants = parseVariants(group, g.line);
    g.seeds = parseSeeds(group, g.line);
    g.frames = parseFrames(group);
    g.timeout_s = parseTimeout(group);
    g.args = runArgs(group);
    const std::vector<std::string> sets = setArgs(group);
    g.args.insert(g.args.end(), sets.begin(), sets.end());
    g.frontend = parseFrontend(group, g.args);
    g.config = parseConfigFile(group);
    mergeInto(g.config, configTable(group));
    g.overrides = parseOverrides(group);
    checkRunCount(g, *plan);
    addRuns(g, overrideConfigs(g), plan);
  }

  struct Override {
    std::string name;
    std::vector<std::string> args;
    toml::table config;
    int line = 0;
  };

  struct GroupSpec {
    std::string name;
    int line = 0;
    std::vector<std::string> datasets, variants;
    std::vector<std::uint64_t> seeds;
    int frames = 0;
    double timeout_s = 0;
    std::vector<std::string> args;
    std::optional<FrontendKind> frontend;
    toml::table config;               // config_file merged with [group.config]
    std::vector<Override> overrides;  // one without name when the group has none
  };

  std::vector<std::string> parseVariants(const toml::table& group, int line) const {
    std::vector<std::string> variants;
    for (const toml::node* node : nonEmptyArray(group, "variants", "a [[group]]", line)) {
      if (!node->is_string()) throw error(*node, "variants must hold strings");
      try {
        for (const std::string& v : expandVariantEntry(**node->as_string())) {
          if (std::find(variants.begin(), variants.end(), v) == variants.end()) {
            variants.push_back(v);
          }
        }
      } catch (const UsageError& e) {
        throw error(*node, e.what());
      }
    }
    return variants;
  }

  std::vector<std::uint64_t> parseSeeds(const toml::table& group, int line,
                                        std::uint64_t default_seed = 1) const {
    if (group.get("seeds") == nullptr) return {default_seed};
    std::vector<std::uint64_t> seeds;
    std::set<std::int64_t> listed;  // linear in the number of seeds, not quadratic
    for (const toml::node* node : nonEmptyArray(group, "seeds", "a [[group]]", line)) {
      const auto seed = node->value<std::int64_t>();
      if (!node->is_integer() || !seed || *seed < 0) {
        throw error(*node, "seeds must be non-negative integers");
      }
      if (!listed.insert(*seed).second) {
        throw error(*node, fmt::format("seed {} is listed twice", *seed));
      }
      seeds.push_back(static_cast<std::uint64_t>(*seed));
    }
    return seeds;
  }

  int parseFrames(const toml::table& group) const {
    const toml::node* node = group.get("frames");
    if (node == nullptr) return 0;
    const auto v = node->value<std::int64_t>();
    if (!node->is_integer() || !v || *v < 0 || *v > 100000000) {
      throw error(*node, "frames must be an integer >= 0 (0: the whole sequence)");
    }
    return static_cast<int>(*v);
  }

  double parseTimeout(const toml::table& group) const {
    const toml::node* node = group.get("timeout_s");
    if (node == nullptr) return 0;
    const auto v = node->value<double>();
    // nan, inf and 1e-300 are numbers too: a limit is whole milliseconds of a finite time.
    if (!v || !std::isfinite(*v) || *v < 0 || (*v > 0 && *v < 1e-3)) {
      throw error(*node, "timeout_s must be 0 (no limit) or a finite number of seconds >= 0.001");
    }
    return *v;
  }

  std::optional<FrontendKind> parseFrontend(const toml::table& group,
                                            const std::vector<std::string>& args) const {
    const toml::node* node = group.get("frontend");
    if (node == nullptr) return std::nullopt;
    const auto v = node->value<std::string>();
    FrontendKind kind = FrontendKind::kAuto;
    if (!v || !parseName(kFrontendKindNames, *v, &kind)) {
      throw error(*node, "frontend must be " + describeNames(kFrontendKindNames, true));
    }
    for (const std::string& arg : args) {
      const std::string option = arg.substr(0, arg.find('='));
      if (option == "--frontend" || option == "--tracks") {
        throw error(*node, "frontend is set here: args must not hold " + option + " too");
      }
    }
    return kind;
  }

  toml::table parseConfigFile(const toml::table& group) const {
    const toml::node* node = group.get("config_file");
    if (node == nullptr) return {};
    if (!node->is_string()) throw error(*node, "config_file must be a string");
    fs::path path(**node->as_string());
    if (path.is_relative()) path = fs::path(base_dir_) / path;
    if (!fs::is_regular_file(path)) {
      throw error(*node, "config_file " + path.string() +
                             (fs::exists(path) ? " is not a file: expected a TOML config file"
                                               : " does not exist"));
    }
    RunConfig probe;
    probe.loadToml(path.string());  // its own errors name its own lines
    try {
      return toml::parse_file(path.string());
    } catch (const toml::parse_error& e) {
      throw InputError(path.string(), lineOf0(e.source()), std::string(e.description()));
    }
  }

  std::vector<Override> parseOverrides(const toml::table& group) const {
    const toml::node* node = group.get("override");
    if (node == nullptr) return {Override{}};
    const toml::array* array = node->as_array();
    if (array == nullptr || !array->is_array_of_tables() || array->empty()) {
      throw error(*node, "override must be an array of tables ([[group.override]])");
    }
    std::vector<Override> overrides;
    for (const toml::node& item : *array) {
      const toml::table& table = *item.as_table();
      checkKeys(table, {"name", "args", "set", "config"}, "a [[group.override]]");
      Override o;
      o.line = lineOf(table);
      o.name = requiredString(table, "name", "a [[group.override]]", o.line);
      if (!validName(o.name)) {
        throw error(*table.get("name"),
                    "override name must use only letters, digits, '_', '-', '.'");
      }
      for (const Override& other : overrides) {
        if (other.name == o.name) {
          throw error(*table.get("name"), "duplicate override name '" + o.name + "'");
        }
      }
      o.args = runArgs(table);
      const std::vector<std::string> sets = setArgs(table);
      o.args.insert(o.args.end(), sets.begin(), sets.end());
      o.config = configTable(table);
      overrides.push_back(std::move(o));
    }
    return overrides;
  }

  void checkRunCount(const GroupSpec& g, const SweepPlan& plan) const {
    const double planned = static_cast<double>(plan.runs.size()) +
                           static_cast<double>(g.datasets.size()) * g.variants.size() *
                               g.seeds.size() * g.overrides.size();
    if (planned > kMaxSweepRuns) {
      throw InputError(name_, g.line,
                       fmt::format("group '{}' brings the sweep to {:.0f} runs; a sweep holds at "
                                   "most {} (split it into several sweeps)",
                                   g.name, planned, kMaxSweepRuns));
    }
  }

  // The merged config of each override, checked once (not once per run).
  std::vector<std::string> overrideConfigs(const GroupSpec& g) const {
    std::vector<std::string> configs;
    for (const Override& o : g.overrides) {
      toml::table config = g.config;
      mergeInto(config, o.config);
      configs.push_back(toTomlText(config));
      checkMergedConfig(configs.back(), o.name.empty() ? g.line : o.line,
                        o.name.empty() ? fmt::format("group '{}'", g.name)
                                       : fmt::format("group '{}', override '{}'", g.name, o.name));
    }
    return configs;
  }

  void addRuns(const GroupSpec& g, const std::vector<std::string>& override_config,
               SweepPlan* plan) {
    for (const std::string& dataset : g.datasets) {
      for (const std::string& variant : g.variants) {
        for (const std::uint64_t seed : g.seeds) {
          for (std::size_t k = 0; k < g.overrides.size(); ++k) {
            plan->runs.push_back(
                plannedRun(g, dataset, variant, seed, g.overrides[k], override_config[k]));
          }
        }
      }
    }
  }

  // One run of the group, checked (options_.check_run) and its id unique in the sweep.
  PlannedRun plannedRun(const GroupSpec& g, const std::string& dataset, const std::string& variant,
                        std::uint64_t seed, const Override& o, const std::string& config_toml) {
    PlannedRun run;
    run.group = g.name;
    run.dataset = dataset;
    run.variant = variant;
    run.seed = seed;
    run.frames = g.frames;
    run.timeout_s = g.timeout_s;
    run.override_name = o.name;
    run.frontend = g.frontend;
    run.extra_args = g.args;
    run.extra_args.insert(run.extra_args.end(), o.args.begin(), o.args.end());
    run.config_toml = config_toml;
    run.line = g.line;
    run.id = fmt::format("{}__{}__{}__s{}", g.name, slug(dataset), variant, seed);
    if (!o.name.empty()) run.id += "__" + o.name;
    if (options_.check_run) {
      const std::string problem = options_.check_run(&run);
      if (!problem.empty()) {
        throw InputError(name_, o.name.empty() ? g.line : o.line,
                         fmt::format("run {}: {}", run.id, problem));
      }
    }
    const auto [earlier, fresh] = planned_ids_.emplace(run.id, g.line);
    if (!fresh) {
      throw InputError(name_, g.line,
                       fmt::format("run {} is planned twice (lines {} and {}): a "
                                   "dataset, variant or seed is listed twice",
                                   run.id, earlier->second, g.line));
    }
    return run;
  }

  // ---- groups of `marglab ba` runs (kind = "ba", sweep_def.h) ----

  // The group's kind: "run" (default) or "ba"; anything else is refused at its line.
  bool isBaGroup(const toml::table& group) const {
    const toml::node* node = group.get("kind");
    if (node == nullptr) return false;
    const auto kind = node->value_exact<std::string>();
    if (!kind || (*kind != "run" && *kind != "ba")) {
      throw error(*node, "kind must be \"run\" (marglab run, the default) or \"ba\" (marglab ba)");
    }
    return *kind == "ba";
  }

  void parseBaGroup(const toml::table& group, SweepPlan* plan) {
    const int line = lineOf(group);
    checkKeys(group,
              {"name", "kind", "problems", "solvers", "seeds", "iterations", "huber_px",
               "perturb_sigma", "normalize_scale", "threads", "isa", "timeout_s"},
              "a [[group]] of kind \"ba\"");
    const std::string name = requiredString(group, "name", "a [[group]]", line);
    if (!validName(name)) {
      throw error(*group.get("name"), "group name must use only letters, digits, '_', '-', '.'");
    }
    std::vector<std::string> problems;
    for (const toml::node* node : nonEmptyArray(group, "problems", "a [[group]]", line)) {
      problems.push_back(resolveProblem(*node));
    }
    const std::vector<BaSolver> solvers = parseSolvers(group, line);
    const std::vector<std::uint64_t> seeds = parseSeeds(group, line, BaOptions{}.seed);
    const BaOptions options = parseBaSettings(group, name, line);
    const std::string isa = parseBaIsa(group);
    const double timeout_s = parseTimeout(group);
    const double planned = static_cast<double>(plan->runs.size()) +
                           static_cast<double>(problems.size()) * solvers.size() * seeds.size();
    if (planned > kMaxSweepRuns) {
      throw InputError(name_, line,
                       fmt::format("group '{}' brings the sweep to {:.0f} runs; a sweep holds at "
                                   "most {} (split it into several sweeps)",
                                   name, planned, kMaxSweepRuns));
    }
    // Seeds outside the solvers: the solvers of one problem and seed run one after the other (the
    // local runner keeps the plan's order within a problem), under the same load of the machine.
    for (const std::string& problem : problems) {
      for (const std::uint64_t seed : seeds) {
        for (const BaSolver solver : solvers) {
          BaRunSpec spec{problem, options, "", isa};
          spec.options.solver = solver;
          spec.options.seed = seed;
          plan->runs.push_back(plannedBaRun(name, line, std::move(spec), timeout_s));
        }
      }
    }
  }

  // The group's `isa` (the kernels of ns / sc), "auto" when not given.
  std::string parseBaIsa(const toml::table& group) const {
    const toml::node* node = group.get("isa");
    if (node == nullptr) return "auto";
    const auto v = node->value_exact<std::string>();
    if (!v || (*v != "auto" && *v != "sse2" && *v != "avx2" && *v != "avx512")) {
      throw error(*node, "isa must be one of \"auto\", \"sse2\", \"avx2\", \"avx512\"");
    }
    return *v;
  }

  // A problem file, relative to the sweep file, read and parsed once per sweep (a malformed file
  // is named with its line before any run starts); its absolute path.
  std::string resolveProblem(const toml::node& node) {
    if (!node.is_string()) throw error(node, "problems must hold strings (BAL files)");
    fs::path path(**node.as_string());
    if (path.is_relative()) path = fs::path(base_dir_) / path;
    const std::string file = fs::absolute(path).lexically_normal().string();
    BaRunSpec probe{file, BaOptions{}, "x.h5"};
    for (const Problem& p : baRunProblems(probe)) {
      throw error(node, fmt::format("problem {}: {}", file, p.message));
    }
    if (checked_problems_.insert(file).second) {
      try {
        loadBalProblem(file);
      } catch (const InputError& e) {
        throw error(node, fmt::format("problem: {}", e.what()));
      }
    }
    return file;
  }

  std::vector<BaSolver> parseSolvers(const toml::table& group, int line) const {
    std::vector<BaSolver> solvers;
    for (const toml::node* node : nonEmptyArray(group, "solvers", "a [[group]]", line)) {
      const auto name = node->value_exact<std::string>();
      if (!name) throw error(*node, "solvers must hold strings");
      std::vector<BaSolver> named;
      try {
        if (*name == "all") {
          for (const std::string& s : baSolverNames()) named.push_back(parseBaSolver(s));
        } else {
          named.push_back(parseBaSolver(*name));
        }
      } catch (const UsageError& e) {
        throw error(*node, fmt::format("solvers: {} (or all)", e.what()));
      }
      for (const BaSolver s : named) {
        if (std::find(solvers.begin(), solvers.end(), s) == solvers.end()) solvers.push_back(s);
      }
    }
    return solvers;
  }

  // The settings of the group's runs, each checked in its range at its key's line (as `marglab
  // ba` checks its option), then together at the group's line.
  BaOptions parseBaSettings(const toml::table& group, const std::string& name, int line) const {
    BaOptions options;
    const auto number = [&](const char* key, double* value) {
      const toml::node* node = group.get(key);
      if (node == nullptr) return;
      if (!node->is_floating_point() && !node->is_integer()) {
        throw error(*node, fmt::format("{} must be a number", key));
      }
      *value = *node->value<double>();
      checkBaSetting(options, *node, key);
    };
    const auto integer = [&](const char* key, int* value) {
      const toml::node* node = group.get(key);
      if (node == nullptr) return;
      const auto v = node->value_exact<std::int64_t>();
      if (!v || *v < 0 || *v > 1000000) {
        throw error(*node, fmt::format("{} must be an integer in [0, 1000000]", key));
      }
      *value = static_cast<int>(*v);
      checkBaSetting(options, *node, key);
    };
    integer("iterations", &options.iterations);
    number("huber_px", &options.huber_px);
    number("perturb_sigma", &options.perturb_sigma);
    number("normalize_scale", &options.normalize_scale);
    integer("threads", &options.threads);
    const std::vector<Problem> problems = validate(options);
    if (!problems.empty()) {
      throw InputError(name_, line, fmt::format("group '{}': {}", name, problems.front().message));
    }
    return options;
  }

  void checkBaSetting(const BaOptions& options, const toml::node& node, const char* key) const {
    const std::vector<Problem> problems = validate(options);
    if (!problems.empty()) throw error(node, fmt::format("{}: {}", key, problems.front().message));
  }

  PlannedRun plannedBaRun(const std::string& group, int line, BaRunSpec spec, double timeout_s) {
    PlannedRun run;
    run.group = group;
    run.dataset = spec.problem;
    run.variant = toString(spec.options.solver);
    run.seed = spec.options.seed;
    run.timeout_s = timeout_s;
    run.line = line;
    run.id = fmt::format("{}__{}__{}__s{}", group, slug(balProblemName(spec.problem)), run.variant,
                         run.seed);
    spec.output = "runs/" + run.id + ".h5";
    const std::vector<Problem> problems = baRunProblems(spec);
    if (!problems.empty()) {
      throw InputError(name_, line, fmt::format("run {}: {}", run.id, problems.front().message));
    }
    run.spec_toml = spec.toToml();
    run.ba = std::move(spec);
    const auto [earlier, fresh] = planned_ids_.emplace(run.id, line);
    if (!fresh) {
      throw InputError(name_, line,
                       fmt::format("run {} is planned twice (lines {} and {}): a problem (or two "
                                   "files of one name), solver or seed is listed twice",
                                   run.id, earlier->second, line));
    }
    return run;
  }

  std::string name_;
  std::map<std::string, int> planned_ids_;
  std::set<std::string>
      checked_problems_;  // problem files parsed once  // run id → line of its group
  struct Listed {
    std::string dataset;
    int line = 0;
  };
  std::map<std::string, Listed> dataset_slugs_;  // slug → the dataset that has it, where listed
  std::string base_dir_;
  const ParseOptions& options_;
  std::vector<std::string> sequences_;
};

}  // namespace

std::string slug(const std::string& text) {
  std::string out = text;
  for (char& c : out) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '-')) c = '-';
  }
  while (!out.empty() && out.front() == '-') out.erase(out.begin());
  return out;
}

std::vector<std::string> expandVariantEntry(const std::string& entry) {
  std::vector<std::string> out;
  if (entry == "paper") {
    for (const Variant& v : paperVariants()) out.push_back(v.name());
  } else if (entry == "headline") {
    out = {"ns-qr-sqrt-f64", "ns-qr-sqrt-f32", "sc-sc-sq-f64", "sc-sc-sq-f32"};
  } else if (entry == "preconditioned") {
    // Issue #31 §3 (docs/preconditioned_storage.md): not paper variants.
    out = {"sc-sc-sqp-f32", "ns-sc-sqp-f32", "sc-sc-sqj-f32", "sc-sc-sqp-f64", "sc-sc-sqrtp-f32"};
  } else if (entry == "precision") {
    // The square-root method in every precision, mixed included (not a paper column).
    out = {"ns-qr-sqrt-f64", "ns-qr-sqrt-f32", "ns-qr-sqrt-mixed"};
  } else if (entry == "ablation") {
    for (const char* method : {"ns-qr-sqrt", "sc-qr-sqrt", "ns-sc-sqrt", "sc-sc-sqrt"}) {
      for (const char* precision : {"f64", "f32"}) {
        out.push_back(std::string(method) + "-" + precision);
      }
    }
  } else {
    try {
      out.push_back(Variant::parse(entry).name());
    } catch (const UsageError& e) {
      throw UsageError(fmt::format(
          "{} (or a set: paper, headline, ablation, precision, preconditioned)", e.what()));
    }
  }
  return out;
}

SweepPlan parseSweep(const std::string& text, const std::string& name, const std::string& base_dir,
                     const ParseOptions& options) {
  return Parser(name, base_dir, options).parse(text);
}

SweepPlan loadSweepFile(const std::string& path, const ParseOptions& options) {
  const std::string text = readTextInput(path, "the sweep file", kSettingsTextLimits);
  const std::string base = fs::absolute(fs::path(path)).parent_path().string();
  return parseSweep(text, path, base, options);
}

std::string sweepTrackFile(const PlannedRun& run) { return "tracks/" + slug(run.dataset) + ".h5"; }

std::string runSpecFile(const PlannedRun& run) { return "runs/" + run.id + ".spec.toml"; }

std::vector<std::string> childArguments(const PlannedRun& run, const std::string& results_path,
                                        const std::string& config_path) {
  if (run.spec_toml.empty()) return runArguments(run, results_path, config_path);
  return {run.ba ? "ba" : "run", "--spec", runSpecFile(run)};
}

std::vector<std::string> runArguments(const PlannedRun& run, const std::string& results_path,
                                      const std::string& config_path) {
  if (run.ba) {
    BaRunSpec spec = *run.ba;
    spec.output = results_path;
    std::vector<std::string> args = spec.arguments();
    args.insert(args.begin(), "ba");
    return args;
  }
  std::vector<std::string> args = {"run",
                                   "--dataset",
                                   run.dataset,
                                   "--variant",
                                   run.variant,
                                   "--seed",
                                   std::to_string(run.seed)};
  if (run.frames > 0) {
    args.push_back("--frames");
    args.push_back(std::to_string(run.frames));
  }
  if (!run.config_toml.empty()) {
    args.push_back("--config");
    args.push_back(config_path);
  }
  if (run.frontend == FrontendKind::kImages) {
    // Tracked once per dataset by the runner: ten variants must not track the images ten times.
    args.push_back("--tracks");
    args.push_back(sweepTrackFile(run));
  } else if (run.frontend) {
    args.push_back("--frontend");
    args.push_back(nameOf(kFrontendKindNames, *run.frontend));
  }
  args.insert(args.end(), run.extra_args.begin(), run.extra_args.end());
  args.push_back("-o");
  args.push_back(results_path);
  return args;
}

}  // namespace marglab::experiment
