// The `marglab` binary as a user runs it: version, help, usage errors, and `verify`.

#include <gtest/gtest.h>

#include "common/cli_runner.h"

namespace marglab {
namespace {

using test::runCli;

TEST(Cli, VersionNamesTheGitRevision) {
  const auto result = runCli("--version");
  EXPECT_EQ(result.exit_code, 0);
  EXPECT_NE(result.output.find("marglab 0."), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("git "), std::string::npos) << result.output;
}

TEST(Cli, HelpListsTheSubcommands) {
  const auto result = runCli("--help");
  EXPECT_EQ(result.exit_code, 0);
  for (const char* verb : {"verify", "datasets"}) {
    EXPECT_NE(result.output.find(verb), std::string::npos) << verb << "\n" << result.output;
  }
}

TEST(Cli, UsageErrorsExitWithTwo) {
  EXPECT_EQ(runCli("").exit_code, 2);
  EXPECT_EQ(runCli("no-such-verb").exit_code, 2);
  EXPECT_EQ(runCli("verify --no-such-option").exit_code, 2);
}

TEST(Cli, VerifyPrintsItsTableAndPasses) {
  const auto result = runCli("verify");
  EXPECT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("| full-rank"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("ill-conditioned k=1e+08"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("f64: all within tolerance"), std::string::npos) << result.output;
  EXPECT_EQ(result.output.find("FAIL"), std::string::npos) << result.output;
}

}  // namespace
}  // namespace marglab
