#include "core/experiment/sweep_index.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>

#include "core/common/error.h"

namespace marglab::experiment {

const std::string& IndexRow::get(const std::string& column) const {
  static const std::string kEmpty;
  const auto it = values.find(column);
  return it == values.end() ? kEmpty : it->second;
}

void IndexRow::setNumber(const std::string& column, double value) {
  values[column] = std::isfinite(value) ? fmt::format("{:.17g}", value)
                   : std::isnan(value)  ? std::string()
                   : value > 0          ? "inf"
                                        : "-inf";
}

double IndexRow::number(const std::string& column) const {
  const std::string& text = get(column);
  if (text.empty()) return std::numeric_limits<double>::quiet_NaN();
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0') return std::numeric_limits<double>::quiet_NaN();
  return v;
}

void FailureCounts::add(const IndexRow& row) {
  const std::string& kind = row.get("failure_kind");
  const std::string& code = row.get("exit_code");
  if (kind == "numerical") {
    ++numerical;
  } else if (kind == "tracking") {
    ++tracking;
  } else if (kind == "error" || (kind == "exit" && (code == "1" || code == "2"))) {
    ++error;
  } else {
    ++crashed;
    ++crashed_kinds[kind.empty() ? "unknown" : kind];
  }
}

std::string FailureCounts::text() const {
  std::string out = fmt::format("{} failed numerically", numerical);
  if (tracking > 0) out += fmt::format(", {} lost tracking", tracking);
  if (error > 0) out += fmt::format(", {} ended with an error", error);
  out += fmt::format(", {} crashed or killed", crashed);
  std::string kinds;
  for (const auto& [kind, n] : crashed_kinds) {
    kinds += fmt::format("{}{} {}", kinds.empty() ? " (" : ", ", n, kind);
  }
  return out + (kinds.empty() ? "" : kinds + ")");
}

const std::vector<std::string>& indexColumns() {
  static const std::vector<std::string> columns = {"id",
                                                   "group",
                                                   "dataset",
                                                   "variant",
                                                   "method",
                                                   "precision",
                                                   "seed",
                                                   "frames",
                                                   "override",
                                                   "status",
                                                   "failure_kind",
                                                   "failure_frame",
                                                   "reason",
                                                   "exit_code",
                                                   "signal",
                                                   "reused",
                                                   "wall_s",
                                                   "n_frames",
                                                   "ate_rmse",
                                                   "duration_s",
                                                   "t_opt_total_s",
                                                   "t_marg_total_s",
                                                   "wall_time_s",
                                                   "realtime_factor",
                                                   "mode",
                                                   "results",
                                                   "log",
                                                   "config",
                                                   "command",
                                                   "pid",
                                                   "slurm_job",
                                                   "started_utc"};
  return columns;
}

std::string csvField(const std::string& value) {
  if (value.find_first_of(",\"\n\r") == std::string::npos) return value;
  std::string out = "\"";
  for (char c : value) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::vector<std::vector<std::string>> parseCsv(const std::string& text, const std::string& name) {
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> row;
  std::string field;
  bool quoted = false;
  bool field_started = false;
  int line = 1;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"') {
        if (i + 1 < text.size() && text[i + 1] == '"') {
          field += '"';
          ++i;
        } else {
          quoted = false;
        }
      } else {
        if (c == '\n') ++line;
        field += c;
      }
      continue;
    }
    if (c == '"') {
      if (field_started && !field.empty()) {
        throw InputError(name, line, "a quote inside an unquoted CSV field");
      }
      quoted = true;
      field_started = true;
    } else if (c == ',') {
      row.push_back(std::move(field));
      field.clear();
      field_started = false;
    } else if (c == '\n' || c == '\r') {
      if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
      row.push_back(std::move(field));
      field.clear();
      field_started = false;
      rows.push_back(std::move(row));
      row.clear();
      ++line;
    } else {
      field += c;
      field_started = true;
    }
  }
  if (quoted) throw InputError(name, line, "unterminated quoted CSV field");
  if (field_started || !row.empty()) {
    row.push_back(std::move(field));
    rows.push_back(std::move(row));
  }
  return rows;
}

const std::vector<std::string>& baIndexColumns() {
  static const std::vector<std::string> columns = {"kind",       "ba_status",    "initial_cost",
                                                   "final_cost", "total_time_s", "peak_rss_mb"};
  return columns;
}

void writeIndex(const std::string& path, const std::vector<IndexRow>& rows) {
  std::string text;
  std::vector<std::string> columns = indexColumns();
  if (std::any_of(rows.begin(), rows.end(),
                  [](const IndexRow& r) { return r.get("kind") == "ba"; })) {
    columns.insert(columns.end(), baIndexColumns().begin(), baIndexColumns().end());
  }
  for (std::size_t c = 0; c < columns.size(); ++c) {
    text += (c ? "," : "") + columns[c];
  }
  text += "\n";
  for (const IndexRow& row : rows) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      if (c) text += ',';
      text += csvField(row.get(columns[c]));
    }
    text += "\n";
  }
  writeFileAtomically(path, text);
}

std::vector<IndexRow> readIndex(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot read the sweep index (is this a sweep folder?)");
  std::stringstream buffer;
  buffer << in.rdbuf();
  const auto table = parseCsv(buffer.str(), path);
  if (table.empty()) throw InputError(path, 0, "empty index");
  const std::vector<std::string>& header = table.front();
  if (std::find(header.begin(), header.end(), "id") == header.end()) {
    throw InputError(path, 1, "the header has no 'id' column");
  }
  std::vector<IndexRow> rows;
  for (std::size_t r = 1; r < table.size(); ++r) {
    if (table[r].size() == 1 && table[r][0].empty()) continue;  // blank line
    if (table[r].size() != header.size()) {
      throw InputError(path, static_cast<int>(r + 1),
                       fmt::format("{} fields, the header has {}", table[r].size(), header.size()));
    }
    IndexRow row;
    for (std::size_t c = 0; c < header.size(); ++c) row.values[header[c]] = table[r][c];
    rows.push_back(std::move(row));
  }
  return rows;
}

}  // namespace marglab::experiment
