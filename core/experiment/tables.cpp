// `marglab tables`: paper values + runs → tables → files (tables.h, writeTables).

#include "core/experiment/tables.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <sstream>

#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/experiment/ba_tables.h"

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

std::vector<std::string> parseFormats(const std::string& text) {
  std::vector<std::string> formats;
  std::stringstream list(text);
  for (std::string f; std::getline(list, f, ',');) {
    if (f != "md" && f != "tex" && f != "csv") {
      throw UsageError("--format takes md, tex and csv separated by commas, not '" + f + "'");
    }
    formats.push_back(f);
  }
  if (formats.empty()) throw UsageError("--format is empty: expected md, tex and/or csv");
  return formats;
}

// A table (or a set's combined tables) as Markdown, LaTeX and CSV.
struct Rendered {
  std::string md, tex, csv;
};

// Writes <base>.<format> for each format; returns the paths.
std::vector<std::string> writeFormats(const std::string& base,
                                      const std::vector<std::string>& formats, const Rendered& r) {
  std::vector<std::string> paths;
  for (const std::string& f : formats) {
    paths.push_back(base + "." + f);
    writeFileAtomically(paths.back(), f == "md" ? r.md : f == "tex" ? r.tex : r.csv);
  }
  return paths;
}

// The files of one table set (tables.h, writeTables); returns the combined ones, adds its
// Markdown to *markdown.
std::vector<std::string> writeSet(const TableSet& set, const std::string& out,
                                  const std::vector<std::string>& formats, std::string* markdown) {
  const std::string suffix = set.override_name.empty() ? "" : "__" + set.override_name;
  const auto base = [&](const std::string& id) { return (fs::path(out) / (id + suffix)).string(); };
  Rendered all{
      set.override_name.empty() ? std::string() : "## Override " + set.override_name + "\n\n", "",
      renderCsv(set.tables, set.override_name)};
  for (const Table& t : set.tables) {
    const Rendered one{renderMarkdown(t), renderLatex(t), renderCsv({t}, set.override_name)};
    all.md += one.md;
    all.tex += one.tex;
    writeFormats(base(t.id), formats, one);
  }
  if (set.claim) {
    const Rendered one{renderMarkdown(*set.claim), renderLatex(*set.claim),
                       renderCsv(*set.claim, set.override_name)};
    all.md += one.md;
    all.tex += one.tex;
    writeFormats(base(set.claim->id), formats, one);
  }
  for (const std::string& why : set.skipped) all.md += "_Not produced: " + why + "._\n\n";
  std::vector<std::string> written = writeFormats(base("tables"), formats, all);
  if (markdown != nullptr) *markdown += all.md;
  fmt::print("tables{}: {} table(s) in {} ({})\n",
             set.override_name.empty() ? "" : " (override " + set.override_name + ")",
             set.tables.size(), out, fmt::join(formats, ", "));
  for (const std::string& why : set.skipped) fmt::print("  not produced: {}\n", why);
  return written;
}

// The tables of `marglab ba` runs (ba_tables.h) go into the set without override.
void addBaTables(const std::vector<BaRunData>& runs, std::vector<TableSet>* sets) {
  auto set = std::find_if(sets->begin(), sets->end(),
                          [](const TableSet& s) { return s.override_name.empty(); });
  if (set == sets->end()) set = sets->insert(sets->begin(), TableSet{});
  for (Table& t : buildBaTables(runs, &set->skipped)) set->tables.push_back(std::move(t));
}

}  // namespace

// Writes the tables; returns the combined files written (tables[__override].md|tex|csv). Shared
// with `marglab reproduce`.
std::vector<std::string> writeTables(const TablesRequest& request, std::string* markdown) {
  const std::vector<std::string> formats = parseFormats(request.formats);
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
  std::vector<std::string> ba_warnings;
  const std::vector<BaRunData> ba_runs = loadBaRuns(request.dirs, &ba_warnings);
  for (const std::string& w : ba_warnings) fmt::print(stderr, "warning: {}\n", w);
  const std::string out =
      request.out.empty() ? (fs::path(request.dirs.front()) / "tables").string() : request.out;
  std::vector<TableSet> sets = results.runs.empty() && !ba_runs.empty()
                                   ? std::vector<TableSet>{TableSet{}}
                                   : buildTables(results, paper, request.seeds);
  if (!ba_runs.empty()) addBaTables(ba_runs, &sets);
  if (request.require_tables) requireSomeTable(sets, request.dirs);
  prepareOutputFolder(out, "--out");
  std::vector<std::string> written;
  for (const TableSet& set : sets) {
    for (std::string& path : writeSet(set, out, formats, markdown)) written.push_back(path);
  }
  return written;
}

}  // namespace marglab::experiment
