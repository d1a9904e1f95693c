// `marglab` — analysis CLI of the marginalization harness. One verb per tools/cmd_<verb>.cpp.

#include <fmt/core.h>

#include <unistd.h>
#include <algorithm>
#include <cstdio>
#include <exception>
#include <memory>

#include "core/common/error.h"
#include "marglab/version.h"
#include "tools/command.h"

namespace marglab::cli {

std::vector<CommandSpec>& registeredCommands() {
  static std::vector<CommandSpec> commands;
  return commands;
}

bool registerCommand(CommandSpec spec) {
  registeredCommands().push_back(std::move(spec));
  return true;
}

bool stderrIsTerminal() { return isatty(fileno(stderr)) != 0; }

}  // namespace marglab::cli

int main(int argc, char** argv) {
  using namespace marglab;
  CLI::App app{"marglab: numerical stability of marginalization in sliding-window estimators"};
  app.set_version_flag("--version",
                       fmt::format("marglab {} (git {})", MARGLAB_VERSION_STRING, MARGLAB_GIT_SHA));
  app.require_subcommand(1);
  app.get_formatter()->column_width(40);

  auto& commands = cli::registeredCommands();
  std::sort(commands.begin(), commands.end(),
            [](const auto& a, const auto& b) { return a.order < b.order; });
  std::vector<std::pair<CLI::App*, cli::CommandRun>> runs;
  for (auto& command : commands) {
    CLI::App* sub = app.add_subcommand(command.name, command.description);
    runs.emplace_back(sub, command.setup(*sub));
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  }

  try {
    for (auto& [sub, run] : runs) {
      if (sub->parsed()) return run();
    }
  } catch (const UsageError& e) {
    fmt::print(stderr, "marglab: usage error: {}\n", e.what());
    return 2;
  } catch (const InputError& e) {
    fmt::print(stderr, "marglab: error: {}\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    fmt::print(stderr, "marglab: error: {}\n", e.what());
    return 1;
  }
  return 2;
}
