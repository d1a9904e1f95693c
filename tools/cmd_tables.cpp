// `marglab tables results/NAME...`: Tables 1–6 of the paper from sweep results (HDF5 files), with
// the paper's published values beside ours, as Markdown, LaTeX (booktabs) and CSV; with runs of the
// dense / nfr marginalization strategies also Hsiung et al.'s Tables I and II (sparsify_table1/2).

#include <fmt/core.h>
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <string>

#include "core/common/error.h"
#include "core/experiment/sweep_index.h"
#include "core/experiment/tables.h"
#include "tools/command.h"
#include "tools/option_checks.h"

namespace marglab {
namespace {

// Tables from folders without a single run would be empty files and a silent exit 0.
void requireRuns(const std::vector<std::string>& dirs) {
  for (const std::string& dir : dirs) {
    const std::string index = (std::filesystem::path(dir) / "index.csv").string();
    if (!std::filesystem::is_regular_file(index)) return;  // writeTables names it
    if (!experiment::readIndex(index).empty()) return;
  }
  throw InputError((std::filesystem::path(dirs.front()) / "index.csv").string(), 0,
                   dirs.size() == 1
                       ? "expected at least one run in the sweep index, found no rows: no tables"
                       : "expected at least one run in the sweep indexes, found no rows in any: "
                         "no tables");
}

const bool kRegistered = cli::registerCommand(
    {"tables",
     "Regenerate Tables 1-6 of the paper (and, for dense / nfr runs, Hsiung et al.'s Tables I and "
     "II) from sweep results, with the papers' values",
     30, [](CLI::App& sub) -> cli::CommandRun {
       auto request = std::make_shared<experiment::TablesRequest>();
       sub.add_option("dirs", request->dirs, "Sweep folders (results/NAME), one or more")
           ->required()
           ->check(cli::existingPath("sweep folder", cli::PathKind::kFolder));
       sub.add_option("--format", request->formats, "Formats, comma-separated: md, tex, csv")
           ->capture_default_str();
       sub.add_option("-o,--out", request->out, "Output folder (default: <first folder>/tables)");
       sub.add_option("--paper-values", request->paper_values,
                      "The paper's values (default: experiments/paper_values.toml of the source)")
           ->check(cli::existingPath("--paper-values", cli::PathKind::kFile));
       auto seeds = std::make_shared<std::string>("auto");
       sub.add_option("--seeds", *seeds,
                      "Tables 1 and 2 as mean ± std over seeds with the failure count (x k/n), "
                      "and the seed claim table: auto (when a cell holds several seeds), on, off")
           ->check(CLI::IsMember({"auto", "on", "off"}))
           ->capture_default_str();
       sub.add_flag("--print", request->print, "Also print the Markdown tables");
       return [request, seeds] {
         experiment::parseSeedStats(*seeds, &request->seeds);
         requireRuns(request->dirs);
         request->require_tables = true;
         std::string md;
         experiment::writeTables(*request, &md);
         if (request->print) fmt::print("\n{}", md);
         return 0;
       };
     }});

}  // namespace
}  // namespace marglab
