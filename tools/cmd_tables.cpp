// `marglab tables results/NAME...`: Tables 1–6 of the paper from sweep results (HDF5 files), with
// the paper's published values beside ours, as Markdown, LaTeX (booktabs) and CSV.

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <sstream>

#include "core/common/error.h"
#include "core/experiment/sweep_index.h"
#include "core/experiment/tables.h"
#include "tools/command.h"

namespace marglab {
namespace cli {

struct TablesRequest {
  std::vector<std::string> dirs;
  std::string formats = "md,tex,csv";
  std::string out;  // default <first dir>/tables
  std::string paper_values;
  bool print = false;
};

// Writes the tables; returns the combined files written (tables[__override].md|tex|csv). Shared
// with `marglab reproduce`.
std::vector<std::string> writeTables(const TablesRequest& request, std::string* markdown) {
  namespace fs = std::filesystem;
  namespace ex = experiment;
  std::vector<std::string> formats;
  std::stringstream list(request.formats);
  for (std::string f; std::getline(list, f, ',');) {
    if (f != "md" && f != "tex" && f != "csv") {
      throw UsageError("--format takes md, tex and csv separated by commas, not '" + f + "'");
    }
    formats.push_back(f);
  }
  for (const std::string& dir : request.dirs) {
    if (!fs::is_regular_file(fs::path(dir) / "index.csv")) {
      throw UsageError(dir + " is not a sweep folder (no index.csv); run `marglab sweep` first");
    }
  }
  const ex::PaperValues paper = ex::loadPaperValues(
      request.paper_values.empty() ? ex::defaultPaperValuesPath() : request.paper_values);
  const ex::ResultSet results = ex::loadResults(request.dirs);
  for (const std::string& w : results.warnings) fmt::print(stderr, "warning: {}\n", w);
  const std::string out =
      request.out.empty() ? (fs::path(request.dirs.front()) / "tables").string() : request.out;
  std::vector<std::string> written;
  for (const ex::TableSet& set : ex::buildTables(results, paper)) {
    const std::string suffix = set.override_name.empty() ? "" : "__" + set.override_name;
    std::string md =
        set.override_name.empty() ? std::string() : "## Override " + set.override_name + "\n\n";
    std::string tex, csv = ex::renderCsv(set.tables, set.override_name);
    for (const ex::Table& t : set.tables) {
      const std::string one_md = ex::renderMarkdown(t);
      const std::string one_tex = ex::renderLatex(t);
      md += one_md;
      tex += one_tex;
      const std::string base = (fs::path(out) / (t.id + suffix)).string();
      for (const std::string& f : formats) {
        const std::string path = base + "." + f;
        ex::writeFileAtomically(path, f == "md"    ? one_md
                                      : f == "tex" ? one_tex
                                                   : ex::renderCsv({t}, set.override_name));
      }
    }
    for (const std::string& why : set.skipped) md += "_Not produced: " + why + "._\n\n";
    const std::string base = (fs::path(out) / ("tables" + suffix)).string();
    for (const std::string& f : formats) {
      const std::string path = base + "." + f;
      ex::writeFileAtomically(path, f == "md" ? md : f == "tex" ? tex : csv);
      written.push_back(path);
    }
    if (markdown != nullptr) *markdown += md;
    fmt::print("tables{}: {} table(s) in {} ({})\n",
               set.override_name.empty() ? "" : " (override " + set.override_name + ")",
               set.tables.size(), out, fmt::join(formats, ", "));
    for (const std::string& why : set.skipped) fmt::print("  not produced: {}\n", why);
  }
  return written;
}

}  // namespace cli

namespace {

const bool kRegistered = cli::registerCommand(
    {"tables", "Regenerate Tables 1-6 of the paper from sweep results, with the paper's values", 30,
     [](CLI::App& sub) -> cli::CommandRun {
       auto request = std::make_shared<cli::TablesRequest>();
       sub.add_option("dirs", request->dirs, "Sweep folders (results/NAME), one or more")
           ->required()
           ->check(CLI::ExistingDirectory);
       sub.add_option("--format", request->formats, "Formats, comma-separated: md, tex, csv")
           ->capture_default_str();
       sub.add_option("-o,--out", request->out, "Output folder (default: <first folder>/tables)");
       sub.add_option("--paper-values", request->paper_values,
                      "The paper's values (default: experiments/paper_values.toml of the source)")
           ->check(CLI::ExistingFile);
       sub.add_flag("--print", request->print, "Also print the Markdown tables");
       return [request] {
         std::string md;
         cli::writeTables(*request, &md);
         if (request->print) fmt::print("\n{}", md);
         return 0;
       };
     }});

}  // namespace
}  // namespace marglab
