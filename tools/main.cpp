// `marglab` — analysis CLI of the marginalization harness. One verb per tools/cmd_<verb>.cpp.

#include <fmt/core.h>

#include <unistd.h>
#include <algorithm>
#include <cstdio>
#include <exception>
#include <memory>
#include <string>
#include <string_view>

#include "core/common/error.h"
#include "core/common/interrupt.h"
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

namespace {

// An unknown first word is an unknown verb (CLI11 would say "A subcommand is required").
bool isUnknownVerb(int argc, char** argv) {
  if (argc < 2 || argv[1][0] == '-') return false;
  const std::string word = argv[1];
  const auto& commands = registeredCommands();
  return std::none_of(commands.begin(), commands.end(),
                      [&](const CommandSpec& c) { return c.name == word; });
}

std::string verbList() {
  std::string list;
  for (const CommandSpec& c : registeredCommands()) list += (list.empty() ? "" : ", ") + c.name;
  return list;
}

// CLI11's message with every overlong word (an echoed argument) shortened; paths stay whole.
std::string shortenedMessage(const std::string& message) {
  constexpr std::size_t kLongestWord = 256;
  std::string out;
  std::size_t start = 0;
  while (start < message.size()) {
    const std::size_t end = std::min(message.find_first_of(" \n", start), message.size());
    const std::string_view word(message.data() + start, end - start);
    out += word.size() > kLongestWord ? shortToken(word) : std::string(word);
    if (end < message.size()) out += message[end];
    start = end + 1;
  }
  return out;
}

}  // namespace
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

  if (cli::isUnknownVerb(argc, argv)) {
    fmt::print(stderr, "marglab: usage error: unknown verb '{}'; the verbs are: {} (see --help)\n",
               shortToken(argv[1]), cli::verbList());
    return 2;
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
    fmt::print(stderr, "{}\nRun with --help for more information.\n",
               cli::shortenedMessage(e.what()));
    return 2;
  } catch (const InputError& e) {  // a missing input path (cli::existingPath)
    fmt::print(stderr, "marglab: error: {}\n", e.what());
    return 1;
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
  } catch (const Interrupted& e) {  // a helper process stopped with us (subprocess.h)
    fmt::print(stderr, "marglab: {}\n", e.what());
    return e.exitCode();
  } catch (const std::exception& e) {
    fmt::print(stderr, "marglab: error: {}\n", e.what());
    return 1;
  }
  return 2;
}
