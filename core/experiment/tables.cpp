// `marglab tables`: paper values + runs → tables → files (tables.h, writeTables).

#include "core/experiment/tables.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <filesystem>
#include <set>
#include <sstream>

#include "core/common/atomic_file.h"
#include "core/common/error.h"

namespace marglab::experiment {

namespace fs = std::filesystem;

namespace {

void requireSomeTable(const std::vector<TableSet>& sets, const std::vector<std::string>& dirs) {
  std::set<std::string> why;
  for (const TableSet& set : sets) {
    if (!set.tables.empty() || set.claim) return;
    why.insert(set.skipped.begin(), set.skipped.end());
  }
  throw InputError((fs::path(dirs.front()) / "index.csv").string(), 0,
                   fmt::format("expected runs that make at least one table, found none ({})",
                               why.empty() ? "no runs" : fmt::format("{}", fmt::join(why, "; "))));
}

}  // namespace

// Writes the tables; returns the combined files written (tables[__override].md|tex|csv). Shared
// with `marglab reproduce`.
std::vector<std::string> writeTables(const TablesRequest& request, std::string* markdown) {
  namespace fs = std::filesystem;
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
      throw InputError((fs::path(dir) / "index.csv").string(), 0,
                       "no such file: not a sweep folder (run `marglab sweep` first)");
    }
  }
  const PaperValues paper = loadPaperValues(request.paper_values.empty() ? defaultPaperValuesPath()
                                                                         : request.paper_values);
  const ResultSet results = loadResults(request.dirs);
  for (const std::string& w : results.warnings) fmt::print(stderr, "warning: {}\n", w);
  const std::string out =
      request.out.empty() ? (fs::path(request.dirs.front()) / "tables").string() : request.out;
  const std::vector<TableSet> sets = buildTables(results, paper, request.seeds);
  if (request.require_tables) requireSomeTable(sets, request.dirs);
  std::vector<std::string> written;
  for (const TableSet& set : sets) {
    const std::string suffix = set.override_name.empty() ? "" : "__" + set.override_name;
    std::string md =
        set.override_name.empty() ? std::string() : "## Override " + set.override_name + "\n\n";
    std::string tex, csv = renderCsv(set.tables, set.override_name);
    for (const Table& t : set.tables) {
      const std::string one_md = renderMarkdown(t);
      const std::string one_tex = renderLatex(t);
      md += one_md;
      tex += one_tex;
      const std::string base = (fs::path(out) / (t.id + suffix)).string();
      for (const std::string& f : formats) {
        const std::string path = base + "." + f;
        writeFileAtomically(path, f == "md"    ? one_md
                                  : f == "tex" ? one_tex
                                               : renderCsv({t}, set.override_name));
      }
    }
    if (set.claim) {
      const std::string one_md = renderMarkdown(*set.claim);
      const std::string one_tex = renderLatex(*set.claim);
      md += one_md;
      tex += one_tex;
      const std::string base = (fs::path(out) / (set.claim->id + suffix)).string();
      for (const std::string& f : formats) {
        writeFileAtomically(base + "." + f, f == "md" ? one_md
                                            : f == "tex"
                                                ? one_tex
                                                : renderCsv(*set.claim, set.override_name));
      }
    }
    for (const std::string& why : set.skipped) md += "_Not produced: " + why + "._\n\n";
    const std::string base = (fs::path(out) / ("tables" + suffix)).string();
    for (const std::string& f : formats) {
      const std::string path = base + "." + f;
      writeFileAtomically(path, f == "md" ? md : f == "tex" ? tex : csv);
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

}  // namespace marglab::experiment
