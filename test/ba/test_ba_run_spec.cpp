// The typed description of one `marglab ba` run (core/ba/ba_run_spec.h): its spec file round-trips
// every setting bit for bit, a malformed spec names its line, baRunProblems names every setting out
// of range and a missing problem, and `marglab ba --spec` runs exactly what the same options run.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/ba/ba_run_spec.h"
#include "core/common/source_dir.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::quote;
using test::runCli;

std::string dubrovnik() { return std::string(sourceDir()) + "/datasets/bal/dubrovnik-3-7-pre.txt"; }

BaRunSpec sampleSpec() {
  BaRunSpec spec;
  spec.problem = dubrovnik();
  spec.options.solver = BaSolver::kScF32;
  spec.options.iterations = 7;
  spec.options.huber_px = 1.0 / 3.0;  // not a short decimal: the text must keep every bit
  spec.options.perturb_sigma = 0.01;
  spec.options.seed = 18446744073709551557ull;  // above 2^63 - 1: a string in TOML
  spec.options.normalize_scale = 100;
  spec.options.threads = 2;
  spec.output = "runs/x.h5";
  spec.isa = "sse2";
  return spec;
}

TEST(BaRunSpec, TomlRoundTripsEverySetting) {
  const BaRunSpec spec = sampleSpec();
  const BaRunSpec back = BaRunSpec::fromTomlString(spec.toToml(), "spec.toml");
  EXPECT_EQ(back.problem, spec.problem);
  EXPECT_EQ(back.output, spec.output);
  EXPECT_EQ(back.options.solver, spec.options.solver);
  EXPECT_EQ(back.options.iterations, spec.options.iterations);
  EXPECT_EQ(back.options.huber_px, spec.options.huber_px);
  EXPECT_EQ(back.options.perturb_sigma, spec.options.perturb_sigma);
  EXPECT_EQ(back.options.seed, spec.options.seed);
  EXPECT_EQ(back.options.normalize_scale, spec.options.normalize_scale);
  EXPECT_EQ(back.options.threads, spec.options.threads);
  EXPECT_EQ(back.isa, spec.isa);
  EXPECT_EQ(back.toToml(), spec.toToml());
}

// Where the spec's TOML is malformed: the message names the line of the key.
void expectError(const std::string& text, const std::string& where, const std::string& what) {
  try {
    BaRunSpec::fromTomlString(text, "spec.toml");
    FAIL() << "accepted:\n" << text;
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(where), std::string::npos) << message;
    EXPECT_NE(message.find(what), std::string::npos) << message;
  }
}

TEST(BaRunSpec, MalformedSpecsNameTheirLine) {
  expectError("[ba]\nproblem = \"p\"\nsolver = \"ns-f16\"\n", "spec.toml:3:", "ns-f32, ns-f64");
  expectError("[ba]\nproblem = \"p\"\nsolver = \"ns-f32\"\nhuber = 1.0\n",
              "spec.toml:4:", "unknown key ba.huber");
  expectError("[ba]\nproblem = \"p\"\nsolver = \"ns-f32\"\niterations = \"50\"\n",
              "spec.toml:4:", "expected an integer");
  expectError("[ba]\nproblem = \"p\"\nsolver = \"ns-f32\"\nseed = -1\n", "spec.toml:4:", "ba.seed");
  expectError("[ba]\nsolver = \"ns-f32\"\n", "spec.toml", "needs a problem");
  expectError("[ba]\nproblem = \"p\"\n", "spec.toml", "needs a solver");
  expectError("[run]\ndataset = \"kitti/10\"\n", "spec.toml:1:", "only [ba]");
}

TEST(BaRunSpec, ProblemsNameEverySettingOutOfRangeAndAMissingProblem) {
  EXPECT_TRUE(baRunProblems(sampleSpec()).empty());
  BaRunSpec spec = sampleSpec();
  spec.problem = "/nonexistent/problem.txt";
  spec.options.huber_px = -1;
  spec.options.threads = 0;
  spec.output.clear();
  const std::vector<Problem> problems = baRunProblems(spec);
  std::string all;
  for (const Problem& p : problems) all += p.file + ": " + p.message + "\n";
  ASSERT_EQ(problems.size(), 4u) << all;
  EXPECT_NE(all.find("/nonexistent/problem.txt: no such problem file"), std::string::npos) << all;
  EXPECT_NE(all.find("no results file"), std::string::npos) << all;
  EXPECT_NE(all.find("--huber -1"), std::string::npos) << all;
  EXPECT_NE(all.find("--threads 0"), std::string::npos) << all;
  spec = sampleSpec();
  spec.problem = std::string(sourceDir()) + "/datasets/bal";
  ASSERT_EQ(baRunProblems(spec).size(), 1u);
  EXPECT_NE(baRunProblems(spec).front().message.find("not a file"), std::string::npos);
}

class BaSpecCli : public test::TempDirTest {};

// `ba --spec FILE` and `ba` with the spec's own arguments() write the same run (ns-f64 on one
// thread is deterministic); a -o beside --spec replaces its output, any other option is refused.
TEST_F(BaSpecCli, SpecAndItsArgumentsRunTheSame) {
  BaRunSpec spec = sampleSpec();
  spec.options.solver = BaSolver::kNsF64;
  spec.options.threads = 1;
  spec.options.seed = 5;
  spec.output = (dir_ / "from_spec.h5").string();
  std::ofstream(dir_ / "run.spec.toml") << spec.toToml();
  const auto by_spec = runCli("ba --json --spec " + quote(dir_ / "run.spec.toml"));
  ASSERT_EQ(by_spec.exit_code, 0) << by_spec.output;
  BaRunSpec by_args_spec = spec;
  by_args_spec.output = (dir_ / "from_args.h5").string();
  std::string args;
  for (const std::string& a : by_args_spec.arguments()) args += " " + quote(a);
  const auto by_args = runCli("ba --json" + args);
  ASSERT_EQ(by_args.exit_code, 0) << by_args.output;
  const auto a = nlohmann::json::parse(by_spec.output), b = nlohmann::json::parse(by_args.output);
  EXPECT_EQ(a["final_cost"].get<double>(), b["final_cost"].get<double>());
  EXPECT_EQ(a["iterations"].size(), b["iterations"].size());
  EXPECT_TRUE(fs::exists(dir_ / "from_spec.h5"));

  const auto moved =
      runCli("ba --spec " + quote(dir_ / "run.spec.toml") + " -o " + quote(dir_ / "moved.h5"));
  EXPECT_EQ(moved.exit_code, 0) << moved.output;
  EXPECT_TRUE(fs::exists(dir_ / "moved.h5"));
  const auto refused = runCli("ba --spec " + quote(dir_ / "run.spec.toml") + " --solver sc-f64");
  EXPECT_EQ(refused.exit_code, 2) << refused.output;
  EXPECT_NE(refused.output.find("cannot be given beside it"), std::string::npos) << refused.output;
}

TEST_F(BaSpecCli, ASpecOutOfRangeExitsTwoWithoutAResultsFile) {
  BaRunSpec spec = sampleSpec();
  spec.options.iterations = -3;
  spec.output = (dir_ / "out.h5").string();
  std::ofstream(dir_ / "run.spec.toml") << spec.toToml();
  const auto result = runCli("ba --spec " + quote(dir_ / "run.spec.toml"));
  EXPECT_EQ(result.exit_code, 2) << result.output;
  EXPECT_NE(result.output.find("--iterations -3"), std::string::npos) << result.output;
  EXPECT_FALSE(fs::exists(dir_ / "out.h5"));
}

}  // namespace
}  // namespace marglab
