#include "core/ba/ba_run_spec.h"

#include <fmt/core.h>
#include <toml++/toml.h>
#include <unistd.h>

#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <sstream>

#include "core/io/text_input.h"

namespace marglab {
namespace {

// Reads the [ba] table key by key; every error names the spec file and the key's line.
class BaTableReader {
 public:
  BaTableReader(std::string name, BaRunSpec* spec) : name_(std::move(name)), spec_(spec) {}

  void read(const toml::table& ba) {
    const std::map<std::string, std::function<void(const toml::node&)>> keys = handlers();
    for (const auto& [key, node] : ba) {
      const auto it = keys.find(std::string(key.str()));
      if (it == keys.end()) {
        throw error(node, fmt::format("unknown key ba.{} (expected one of: problem, solver, "
                                      "iterations, huber_px, perturb_sigma, seed, "
                                      "normalize_scale, threads, isa, output)",
                                      key.str()));
      }
      it->second(node);
    }
    if (spec_->problem.empty()) throw InputError(name_, 0, "[ba] needs a problem");
    if (ba.get("solver") == nullptr) throw InputError(name_, 0, "[ba] needs a solver");
  }

 private:
  std::map<std::string, std::function<void(const toml::node&)>> handlers() {
    BaRunSpec& s = *spec_;
    BaOptions& o = s.options;
    return {
        {"problem", [&](const toml::node& n) { s.problem = text(n, "problem"); }},
        {"solver", [&](const toml::node& n) { o.solver = solver(n); }},
        {"iterations", [&](const toml::node& n) { o.iterations = integer(n, "iterations"); }},
        {"huber_px", [&](const toml::node& n) { o.huber_px = number(n, "huber_px"); }},
        {"perturb_sigma",
         [&](const toml::node& n) { o.perturb_sigma = number(n, "perturb_sigma"); }},
        {"seed", [&](const toml::node& n) { o.seed = seed(n); }},
        {"normalize_scale",
         [&](const toml::node& n) { o.normalize_scale = number(n, "normalize_scale"); }},
        {"threads", [&](const toml::node& n) { o.threads = integer(n, "threads"); }},
        {"isa", [&](const toml::node& n) { s.isa = text(n, "isa"); }},
        {"output", [&](const toml::node& n) { s.output = text(n, "output"); }},
    };
  }

  InputError error(const toml::node& node, const std::string& what) const {
    return InputError(name_, static_cast<int>(node.source().begin.line), what);
  }
  std::string text(const toml::node& node, const char* key) const {
    const auto v = node.value_exact<std::string>();
    if (!v) throw error(node, fmt::format("expected a string for ba.{}", key));
    return *v;
  }
  // Ranges are checked by baRunProblems, as for the verb's options.
  int integer(const toml::node& node, const char* key) const {
    const auto v = node.value_exact<std::int64_t>();
    if (!v || *v < std::numeric_limits<int>::min() || *v > std::numeric_limits<int>::max()) {
      throw error(node, fmt::format("expected an integer for ba.{}", key));
    }
    return static_cast<int>(*v);
  }
  double number(const toml::node& node, const char* key) const {
    if (!node.is_floating_point() && !node.is_integer()) {
      throw error(node, fmt::format("expected a number for ba.{}", key));
    }
    return *node.value<double>();
  }
  std::uint64_t seed(const toml::node& node) const {
    if (const auto v = node.value_exact<std::int64_t>(); v && *v >= 0) {
      return static_cast<std::uint64_t>(*v);
    }
    const auto s = node.value_exact<std::string>();
    try {
      std::size_t used = 0;
      if (s && !s->empty() && s->front() != '-') {
        const unsigned long long value = std::stoull(*s, &used);
        if (used == s->size()) return value;
      }
    } catch (const std::exception&) {
    }
    throw error(node, "expected an integer in [0, 2^64 - 1] for ba.seed (a string above 2^63 - 1)");
  }
  BaSolver solver(const toml::node& node) const {
    try {
      return parseBaSolver(text(node, "solver"));
    } catch (const UsageError& e) {
      throw error(node, fmt::format("ba.solver: {}", e.what()));
    }
  }

  std::string name_;
  BaRunSpec* spec_;
};

}  // namespace

std::string BaRunSpec::toToml() const {
  toml::table ba;
  ba.insert("problem", problem);
  ba.insert("solver", toString(options.solver));
  ba.insert("iterations", options.iterations);
  ba.insert("huber_px", options.huber_px);
  ba.insert("perturb_sigma", options.perturb_sigma);
  // TOML integers are signed 64-bit: a larger seed is written as a string.
  if (options.seed <= static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
    ba.insert("seed", static_cast<std::int64_t>(options.seed));
  } else {
    ba.insert("seed", std::to_string(options.seed));
  }
  ba.insert("normalize_scale", options.normalize_scale);
  ba.insert("threads", options.threads);
  ba.insert("isa", isa);
  ba.insert("output", output);
  toml::table root;
  root.insert("ba", std::move(ba));
  std::ostringstream out;
  out << "# marglab ba spec (core/ba/ba_run_spec.h): `marglab ba --spec FILE` repeats it\n"
      << root << "\n";
  return out.str();
}

BaRunSpec BaRunSpec::fromTomlString(const std::string& text, const std::string& name) {
  toml::table root;
  try {
    root = toml::parse(text, name);
  } catch (const toml::parse_error& e) {
    throw InputError(name, static_cast<int>(e.source().begin.line), std::string(e.description()));
  }
  for (const auto& [key, node] : root) {
    if (key.str() != "ba") {
      throw InputError(
          name, static_cast<int>(key.source().begin.line),
          fmt::format("unknown table or key '{}' (a ba spec has only [ba])", key.str()));
    }
  }
  const toml::table* ba = root["ba"].as_table();
  if (ba == nullptr) throw InputError(name, 0, "expected a [ba] table (a ba spec file)");
  BaRunSpec spec;
  BaTableReader(name, &spec).read(*ba);
  return spec;
}

BaRunSpec BaRunSpec::fromTomlFile(const std::string& path) {
  return fromTomlString(readTextInput(path, "the ba spec file", kSettingsTextLimits), path);
}

std::vector<std::string> BaRunSpec::arguments() const {
  const BaOptions& o = options;
  std::vector<std::string> args = {"--problem",    problem,
                                   "--solver",     toString(o.solver),
                                   "--iterations", std::to_string(o.iterations),
                                   "--huber",      fmt::format("{}", o.huber_px),
                                   "--perturb",    fmt::format("{}", o.perturb_sigma),
                                   "--seed",       std::to_string(o.seed),
                                   "--normalize",  fmt::format("{}", o.normalize_scale)};
  if (o.threads != 1) {
    args.push_back("--threads");
    args.push_back(std::to_string(o.threads));
  }
  if (isa != "auto") {
    args.push_back("--isa");
    args.push_back(isa);
  }
  args.push_back("-o");
  args.push_back(output);
  return args;
}

std::vector<Problem> baRunProblems(const BaRunSpec& spec) {
  std::vector<Problem> problems;
  std::error_code ec;
  if (spec.problem.empty()) {
    problems.push_back({ProblemKind::kUsage, "", 0, "no problem file (--problem)"});
  } else if (!std::filesystem::is_regular_file(spec.problem, ec)) {
    problems.push_back({ProblemKind::kInput, spec.problem, 0,
                        std::filesystem::exists(spec.problem, ec)
                            ? "the problem is not a file: expected a BAL file, plain or .bz2"
                            : "no such problem file"});
  } else if (::access(spec.problem.c_str(), R_OK) != 0) {
    problems.push_back({ProblemKind::kInput, spec.problem, 0, "the problem file is not readable"});
  }
  if (spec.output.empty()) {
    problems.push_back({ProblemKind::kUsage, "", 0, "no results file (-o)"});
  }
  for (Problem& p : validate(spec.options)) problems.push_back(std::move(p));
  if (spec.isa != "auto" && spec.isa != "sse2" && spec.isa != "avx2" && spec.isa != "avx512") {
    problems.push_back({ProblemKind::kUsage, "", 0,
                        fmt::format("isa {}: expected auto, sse2, avx2 or avx512", spec.isa)});
  }
  return problems;
}

}  // namespace marglab
