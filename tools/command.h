#pragma once
// Subcommand registry of the `marglab` CLI. Each tools/cmd_<verb>.cpp registers one verb at static
// initialization, so adding a subcommand means adding one file:
//
//   namespace { const bool kRegistered = marglab::cli::registerCommand(
//       {"verify", "…", 70, [](CLI::App& app) { …options…; return [=] { return run(…); }; }}); }
//
// The run function returns the process exit code: 0 success, 1 runtime error. Bad input is thrown
// as marglab::InputError (exit 1), usage errors as marglab::UsageError or CLI11 errors (exit 2).

#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <vector>

namespace marglab::cli {

using CommandRun = std::function<int()>;

struct CommandSpec {
  std::string name;
  std::string description;
  int order;  // position in --help
  std::function<CommandRun(CLI::App& sub)> setup;
};

bool registerCommand(CommandSpec spec);
std::vector<CommandSpec>& registeredCommands();

// True when stderr is a terminal: progress lines are shown only then.
bool stderrIsTerminal();

}  // namespace marglab::cli
