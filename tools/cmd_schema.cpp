// `marglab schema`: the results-file schema (core/io/results_schema.h) as JSON — the file
// tools/scripts/results_schema.json the Python reader validates against — or as the Markdown
// tables of docs/design.md §6. test/io checks that both committed copies are current.

#include <fmt/core.h>

#include <memory>

#include "core/io/results_schema.h"
#include "tools/command.h"

namespace marglab {
namespace {

const bool kRegistered = cli::registerCommand(
    {"schema", "The results-file schema as JSON (--json) or as the design doc's Markdown tables",
     75, [](CLI::App& sub) -> cli::CommandRun {
       auto markdown = std::make_shared<bool>(false);
       auto* json = sub.add_flag("--json", "JSON, for tools/scripts/results_schema.json (default)");
       sub.add_flag("--markdown", *markdown, "The tables of docs/design.md §6")->excludes(json);
       return [markdown] {
         fmt::print("{}",
                    *markdown ? results_schema::schemaMarkdown() : results_schema::schemaJson());
         return 0;
       };
     }});

}  // namespace
}  // namespace marglab
