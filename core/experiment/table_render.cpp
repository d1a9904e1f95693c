// Tables as Markdown, LaTeX and CSV (tables.h: formatCell, render*).

#include "core/experiment/tables.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <utility>

namespace marglab::experiment {

namespace {

int decimalsOf(const TableRow& row, const TableColumn& column, bool ours) {
  if (column.decimals >= 0) return column.decimals;
  return ours ? row.ours_decimals : row.paper_decimals;
}

// Seed statistics after a cell's value: " ± std" (with two or more ok seeds) per quantity, in
// the row's notation.
std::string spreadText(const TableCell& cell, std::size_t q, int decimals, bool scientific,
                       const char* pm) {
  if (!cell.seed_stats || q >= cell.spread.size() || !std::isfinite(cell.spread[q])) return "";
  return scientific ? fmt::format("{}{:.{}e}", pm, cell.spread[q], std::min(decimals, 1))
                    : fmt::format("{}{:.{}f}", pm, cell.spread[q], decimals);
}

// The failure count of a seed-statistics cell: "x k/n" ("" when none failed).
std::string failedText(const TableCell& cell, const char* space) {
  if (!cell.seed_stats || cell.n_failed == 0) return "";
  return fmt::format("x{}{}/{}", space, cell.n_failed, cell.n_runs);
}

std::string cellMarkdown(const TableCell& cell, const TableRow& row, const TableColumn& column,
                         bool ours) {
  const int decimals = decimalsOf(row, column, ours);
  if (cell.state == TableCell::State::kFailed && cell.seed_stats) return failedText(cell, " ");
  if (cell.state != TableCell::State::kValue) {
    return formatCell(cell, 0, decimals, row.suffix, row.scientific);
  }
  std::vector<std::string> parts;
  for (std::size_t q = 0; q < cell.numbers.size(); ++q) {
    const std::string text = formatCell(cell, q, decimals, row.suffix, row.scientific);
    parts.push_back((cell.best.size() > q && cell.best[q] ? "**" + text + "**" : text) +
                    spreadText(cell, q, decimals, row.scientific, " ± "));
  }
  const std::string failed = failedText(cell, " ");
  return fmt::format("{}", fmt::join(parts, " / ")) + (failed.empty() ? "" : " " + failed);
}

std::string cellLatex(const TableCell& cell, const TableRow& row, const TableColumn& column,
                      bool ours) {
  const int decimals = decimalsOf(row, column, ours);
  if (cell.state == TableCell::State::kMissing) return "--";
  if (cell.state == TableCell::State::kFailed) {
    return cell.seed_stats ? failedText(cell, "~") : "x";
  }
  std::vector<std::string> parts;
  for (std::size_t q = 0; q < cell.numbers.size(); ++q) {
    const std::string text = formatCell(cell, q, decimals, row.suffix, row.scientific);
    parts.push_back((cell.best.size() > q && cell.best[q] ? "\\textbf{" + text + "}" : text) +
                    spreadText(cell, q, decimals, row.scientific, " $\\pm$ "));
  }
  const std::string failed = failedText(cell, "~");
  return fmt::format("{}", fmt::join(parts, " / ")) + (failed.empty() ? "" : " " + failed);
}

std::string csvNumber(double v) { return std::isfinite(v) ? fmt::format("{:.17g}", v) : ""; }

const char* stateName(TableCell::State s) {
  return s == TableCell::State::kValue    ? "ok"
         : s == TableCell::State::kFailed ? "failed"
                                          : "missing";
}

std::string texEscape(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '_' || c == '%' || c == '&' || c == '#' || c == '$') out += '\\';
    out += c;
  }
  return out;
}

// Replaces the markdown-only glyphs of notes for LaTeX.
std::string texNote(const std::string& note) {
  std::string out = texEscape(note);
  for (const auto& [from, to] :
       std::vector<std::pair<std::string, std::string>>{{"√", "$\\sqrt{}$"},
                                                        {"–", "--"},
                                                        {"Σ", "$\\Sigma$"},
                                                        {"×", "$\\times$"},
                                                        {"σ", "$\\sigma$"},
                                                        {"`", ""}}) {
    for (std::size_t p = out.find(from); p != std::string::npos;
         p = out.find(from, p + to.size())) {
      out.replace(p, from.size(), to);
    }
  }
  return out;
}

}  // namespace

std::string formatCell(const TableCell& cell, std::size_t component, int decimals,
                       const std::string& suffix, bool scientific) {
  if (cell.state == TableCell::State::kFailed) return "x";
  if (cell.state == TableCell::State::kMissing || component >= cell.numbers.size()) return "–";
  const double v = cell.numbers[component];
  if (std::isnan(v)) return "nan";
  return scientific ? fmt::format("{:.{}e}{}", v, decimals, suffix)
                    : fmt::format("{:.{}f}{}", v, decimals, suffix);
}

std::string renderMarkdown(const Table& table) {
  std::string out = "### " + table.title + "\n\n| " + table.row_header + " |";
  const bool frames = std::any_of(table.rows.begin(), table.rows.end(),
                                  [](const TableRow& r) { return !r.frames.empty(); });
  if (frames) out += " frames |";
  for (const TableColumn& c : table.columns) {
    out += fmt::format(" {} |{}", c.label_md, table.has_paper ? " paper |" : "");
  }
  out += "\n|---|";
  if (frames) out += "---:|";
  for (std::size_t i = 0; i < table.columns.size(); ++i) {
    out += table.has_paper ? "---:|---:|" : "---:|";
  }
  out += "\n";
  for (const TableRow& row : table.rows) {
    out += "| " + row.label + " |";
    if (frames) out += " " + row.frames + " |";
    for (std::size_t c = 0; c < table.columns.size(); ++c) {
      out += " " + cellMarkdown(row.ours[c], row, table.columns[c], true) + " |";
      if (table.has_paper) {
        out += " " + cellMarkdown(row.paper[c], row, table.columns[c], false) + " |";
      }
    }
    out += "\n";
  }
  out += "\n";
  for (const std::string& note : table.notes) out += note + "\n";
  return out + "\n";
}

std::string renderLatex(const Table& table) {
  const bool frames = std::any_of(table.rows.begin(), table.rows.end(),
                                  [](const TableRow& r) { return !r.frames.empty(); });
  const std::size_t lead = frames ? 2 : 1;
  std::string out =
      "% " + table.title + " (marglab tables; needs \\usepackage{booktabs,amsmath})\n";
  out += "\\begin{table}[t]\n\\centering\n\\small\n";
  out += "\\begin{tabular}{l" + std::string(frames ? "r" : "");
  for (std::size_t i = 0; i < table.columns.size(); ++i) out += table.has_paper ? "rr" : "r";
  out += "}\n\\toprule\n" + texEscape(table.row_header) + (frames ? " & frames" : "");
  for (const TableColumn& c : table.columns) {
    out += table.has_paper ? " & \\multicolumn{2}{c}{" + c.label_tex + "}" : " & " + c.label_tex;
  }
  out += " \\\\\n";
  if (table.has_paper) {
    for (std::size_t i = 0; i < table.columns.size(); ++i) {
      out += fmt::format("\\cmidrule(lr){{{}-{}}}", lead + 1 + 2 * i, lead + 2 + 2 * i);
    }
    out += "\n" + std::string(frames ? " & " : "");
    for (std::size_t i = 0; i < table.columns.size(); ++i) out += " & ours & paper";
    out += " \\\\\n";
  }
  out += "\\midrule\n";
  for (const TableRow& row : table.rows) {
    out += texEscape(row.label);
    if (frames) out += " & " + row.frames;
    for (std::size_t c = 0; c < table.columns.size(); ++c) {
      out += " & " + cellLatex(row.ours[c], row, table.columns[c], true);
      if (table.has_paper) out += " & " + cellLatex(row.paper[c], row, table.columns[c], false);
    }
    out += " \\\\\n";
  }
  out += "\\bottomrule\n\\end{tabular}\n\\caption{" + texNote(table.title) + ". ";
  for (const std::string& note : table.notes) out += texNote(note) + " ";
  out += "}\n\\label{tab:marglab-" + table.id + "}\n\\end{table}\n\n";
  return out;
}

std::string renderCsv(const std::vector<Table>& tables, const std::string& override_name) {
  std::string out =
      "table,override,row,label,frames,column,variant,quantity,ours,ours_state,ours_best,n_runs,"
      "paper,paper_state,paper_best,ours_std,ours_failed\n";
  for (const Table& t : tables) {
    for (const TableRow& row : t.rows) {
      for (std::size_t c = 0; c < t.columns.size(); ++c) {
        for (std::size_t q = 0; q < t.quantities.size(); ++q) {
          const std::string quantity = !t.columns[c].quantity.empty() ? t.columns[c].quantity
                                       : t.quantities[q] == "value"   ? row.key
                                                                      : t.quantities[q];
          const TableCell& ours = row.ours[c];
          const TableCell& paper = row.paper[c];
          const auto number = [&](const TableCell& cell) {
            return cell.state == TableCell::State::kValue && q < cell.numbers.size()
                       ? csvNumber(cell.numbers[q])
                       : std::string();
          };
          const auto best = [&](const TableCell& cell) {
            return cell.best.size() > q && cell.best[q] ? "1" : "0";
          };
          const std::vector<std::string> fields = {
              t.id,
              override_name,
              row.key,
              row.label,
              row.frames,
              t.columns[c].label_md,
              t.columns[c].variant,
              quantity,
              number(ours),
              stateName(ours.state),
              best(ours),
              std::to_string(ours.n_runs),
              number(paper),
              stateName(paper.state),
              best(paper),
              ours.seed_stats && q < ours.spread.size() ? csvNumber(ours.spread[q]) : std::string(),
              ours.seed_stats ? std::to_string(ours.n_failed) : std::string()};
          for (std::size_t f = 0; f < fields.size(); ++f) {
            out += (f ? "," : "") + csvField(fields[f]);
          }
          out += "\n";
        }
      }
    }
  }
  return out;
}

namespace {

std::string claimNumber(double v, int decimals) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, decimals) : "–";
}

// Differences can be far below the ATE's 4 decimals: two significant digits.
std::string claimDifference(double v) { return std::isfinite(v) ? fmt::format("{:.1e}", v) : "–"; }

std::string claimPercent(double v) {
  return std::isfinite(v) ? fmt::format("{:.2f} %", 100 * v) : "–";
}

// "mean ± std" of one variant's ok seeds.
std::string claimSpread(double mean, double std, const char* pm) {
  return claimNumber(mean, 4) + (std::isfinite(std) ? pm + claimNumber(std, 4) : "");
}

// "ok/finished" seeds of one variant.
std::string claimSeeds(int finished, int failed) {
  return fmt::format("{}/{}", finished - failed, finished);
}

}  // namespace

std::string renderMarkdown(const SeedClaim& claim) {
  std::string out = "### " + claim.title + "\n\n";
  out +=
      "| sequence | seeds √-f64 | √-f64 ATE [m] | seeds √-f32 | √-f32 ATE [m] | abs(Δ) [m] | "
      "abs(Δ) / √-f64 | paired abs(Δ) [m] | within |\n|---|---:|---:|---:|---:|---:|---:|---:|:"
      "---:|\n";
  for (const SeedClaimRow& r : claim.rows) {
    out += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", r.label,
                       claimSeeds(r.seeds_64, r.failed_64), claimSpread(r.mean_64, r.std_64, " ± "),
                       claimSeeds(r.seeds_32, r.failed_32), claimSpread(r.mean_32, r.std_32, " ± "),
                       claimDifference(r.delta), claimPercent(r.relative),
                       claimDifference(r.paired), r.verdict);
  }
  out += "\n";
  for (const std::string& note : claim.notes) out += note + "\n";
  return out + "\n";
}

std::string renderLatex(const SeedClaim& claim) {
  std::string out =
      "% " + claim.title + " (marglab tables; needs \\usepackage{booktabs,amsmath})\n";
  out += "\\begin{table}[t]\n\\centering\n\\small\n\\begin{tabular}{lrrrrrrrc}\n\\toprule\n";
  out +=
      "sequence & seeds & $\\sqrt{\\text{f64}}$ ATE [m] & seeds & $\\sqrt{\\text{f32}}$ ATE [m] & "
      "$|\\Delta|$ [m] & $|\\Delta|$ / f64 & paired $|\\Delta|$ [m] & within \\\\\n\\midrule\n";
  for (const SeedClaimRow& r : claim.rows) {
    out += fmt::format(
        "{} & {} & {} & {} & {} & {} & {} & {} & {} \\\\\n", texEscape(r.label),
        claimSeeds(r.seeds_64, r.failed_64), claimSpread(r.mean_64, r.std_64, " $\\pm$ "),
        claimSeeds(r.seeds_32, r.failed_32), claimSpread(r.mean_32, r.std_32, " $\\pm$ "),
        claimDifference(r.delta), texEscape(claimPercent(r.relative)), claimDifference(r.paired),
        r.verdict == "–" ? "--" : r.verdict);
  }
  out += "\\bottomrule\n\\end{tabular}\n\\caption{" + texNote(claim.title) + ". ";
  for (const std::string& note : claim.notes) out += texNote(note) + " ";
  return out + "}\n\\label{tab:marglab-" + claim.id + "}\n\\end{table}\n\n";
}

std::string renderCsv(const SeedClaim& claim, const std::string& override_name) {
  std::string out =
      "table,override,row,label,seeds_f64,failed_f64,mean_f64,std_f64,seeds_f32,failed_f32,"
      "mean_f32,std_f32,delta,relative,paired,within\n";
  for (const SeedClaimRow& r : claim.rows) {
    const std::vector<std::string> fields = {claim.id,
                                             override_name,
                                             r.key,
                                             r.label,
                                             std::to_string(r.seeds_64),
                                             std::to_string(r.failed_64),
                                             csvNumber(r.mean_64),
                                             csvNumber(r.std_64),
                                             std::to_string(r.seeds_32),
                                             std::to_string(r.failed_32),
                                             csvNumber(r.mean_32),
                                             csvNumber(r.std_32),
                                             csvNumber(r.delta),
                                             csvNumber(r.relative),
                                             csvNumber(r.paired),
                                             r.verdict == "–" ? "" : r.verdict};
    for (std::size_t f = 0; f < fields.size(); ++f) out += (f ? "," : "") + csvField(fields[f]);
    out += "\n";
  }
  return out;
}

}  // namespace marglab::experiment
