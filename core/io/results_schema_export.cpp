// The schema tables as JSON (for the Python reader) and as the Markdown of docs/design.md §6.

#include <fmt/format.h>

#include <string>
#include <vector>

#include "core/common/json.h"
#include "core/io/results_schema.h"

namespace marglab::results_schema {
namespace {

template <class S>
const char* elementName() {
  if constexpr (std::is_same_v<S, std::int64_t>) return "int64";
  if constexpr (std::is_same_v<S, std::int32_t>) return "int32";
  if constexpr (std::is_same_v<S, std::uint8_t>) return "uint8";
  if constexpr (std::is_same_v<S, double>) return "f64";
}

// The names of a row's values (empty for one value per row and for ragged columns).
template <class T>
std::vector<std::string> axesOf() {
  if constexpr (std::is_same_v<T, Eigen::Vector3d>) return {"x", "y", "z"};
  if constexpr (std::is_same_v<T, Eigen::Quaterniond>) return {"x", "y", "z", "w"};
  if constexpr (std::is_same_v<T, Vec7d>) {
    return {kGaugeDirectionNames.begin(), kGaugeDirectionNames.end()};
  }
  return {};
}

struct ColumnFacts {
  std::string type;  // element type
  int width;         // 0: one value per row, kRagged: ragged
  std::vector<std::string> axes;
};

template <class Record>
ColumnFacts factsOf(const Member<Record>& member) {
  return std::visit(
      [](auto m) {
        using T = MemberType<decltype(m)>;
        return ColumnFacts{elementName<typename Stored<T>::type>(), Stored<T>::kWidth, axesOf<T>()};
      },
      member);
}

std::string attributeType(const AttributeMember& member) {
  return std::visit(
      [](auto m) -> std::string {
        using T = MemberType<decltype(m)>;
        if constexpr (std::is_same_v<T, std::string>) return "str";
        if constexpr (std::is_same_v<T, double>) return "f64";
        return "int64";  // the uint64 seed as its bit pattern
      },
      member);
}

std::string summaryType(const SummaryMember& member) {
  return std::visit(
      [](auto m) -> std::string {
        using T = MemberType<decltype(m)>;
        if constexpr (std::is_same_v<T, std::int64_t>) return "int64";
        if constexpr (std::is_same_v<T, double>) return "f64";
        if constexpr (!std::is_arithmetic_v<T>) return fmt::format("f64[{}]", T::SizeAtCompileTime);
      },
      member);
}

template <class Record>
Json tableJson(const Table<Record>& table) {
  Json columns = Json::array();
  for (const Column<Record>& c : table.columns) {
    const ColumnFacts facts = factsOf(c.member);
    Json column{{"name", c.name},
                {"type", facts.type},
                {"width", facts.width},
                {"axes", facts.axes},
                {"unit", c.unit},
                {"required", c.presence == Presence::kRequired},
                {"written_by", c.origin == Origin::kFinish ? "finish" : "append"},
                {"description", c.description}};
    columns.push_back(std::move(column));
  }
  return Json{{"name", table.group}, {"description", table.description}, {"columns", columns}};
}

// A table cell: '|' would end it.
std::string cell(const std::string& text) {
  std::string out;
  for (const char c : text) out += c == '|' ? std::string("\\|") : std::string(1, c);
  return out;
}

std::string shapeOf(const ColumnFacts& facts, const char* rows) {
  if (facts.width == kRagged)
    return fmt::format("ragged: values f64 [K], offsets int64 [{}+1]", rows);
  if (facts.width == 0) return fmt::format("{} ({})", facts.type, rows);
  return fmt::format("{} ({},{}): {}", facts.type, rows, facts.width, fmt::join(facts.axes, " "));
}

template <class Record>
std::string tableMarkdown(const Table<Record>& table, const char* rows) {
  std::string out = fmt::format(
      "**`/{}`** — {}:\n\n| dataset | type, shape | unit | content |\n"
      "|---|---|---|---|\n",
      table.group, table.description);
  for (const Column<Record>& c : table.columns) {
    std::string content = c.description;
    if (c.presence == Presence::kOptional) content += " (absent in older files)";
    if (c.origin == Origin::kFinish) content += " (written by finish())";
    out += fmt::format("| `{}` | {} | {} | {} |\n", c.name, shapeOf(factsOf(c.member), rows),
                       c.unit, cell(content));
  }
  return out + "\n";
}

std::string quotedValues(const std::vector<const char*>& values) {
  std::vector<std::string> quoted;
  for (const char* v : values) quoted.push_back(*v ? fmt::format("`{}`", v) : "`\"\"`");
  return fmt::format("{}", fmt::join(quoted, " \\| "));
}

std::string attributesMarkdown() {
  std::string out =
      "**`/` attributes** (and, as further strings, `RunMetadata::extra`):\n\n"
      "| attribute | type | values | content |\n|---|---|---|---|\n";
  for (const Attribute& a : rootAttributes()) {
    out += fmt::format("| `{}` | {} | {} | {}{} |\n", a.name, attributeType(a.member),
                       quotedValues(a.values), cell(a.description),
                       a.presence == Presence::kOptional ? " (absent in older files)" : "");
  }
  return out + "\n";
}

std::string summaryMarkdown() {
  std::string out =
      "**`/summary` attributes**:\n\n| attribute | type | unit | content |\n|---|---|---|---|\n";
  for (const SummaryAttribute& a : summaryAttributes()) {
    out += fmt::format("| `{}` | {} | {} | {} |\n", a.name, summaryType(a.member), a.unit,
                       cell(a.description));
  }
  return out;
}

}  // namespace

std::string schemaJson() {
  Json root = Json::array();
  for (const Attribute& a : rootAttributes()) {
    std::vector<std::string> values(a.values.begin(), a.values.end());
    root.push_back(Json{{"name", a.name},
                        {"type", attributeType(a.member)},
                        {"values", values},
                        {"required", a.presence == Presence::kRequired},
                        {"description", a.description}});
  }
  Json summary = Json::array();
  for (const SummaryAttribute& a : summaryAttributes()) {
    summary.push_back(Json{{"name", a.name},
                           {"type", summaryType(a.member)},
                           {"unit", a.unit},
                           {"description", a.description}});
  }
  const Json schema{{"generated_by", "marglab schema --json (core/io/results_schema.cpp)"},
                    {"schema_version", kResultsSchemaVersion},
                    {"readable_versions", readableVersions()},
                    {"root_attributes", root},
                    {"groups",
                     {tableJson(frameTable()), tableJson(margTable()), tableJson(sparsifyTable()),
                      tableJson(frontendTable())}},
                    {"summary_attributes", summary}};
  return schema.dump(1) + "\n";
}

std::string schemaMarkdown() {
  return attributesMarkdown() + tableMarkdown(frameTable(), "n") + tableMarkdown(margTable(), "m") +
         tableMarkdown(sparsifyTable(), "k") + tableMarkdown(frontendTable(), "f") +
         summaryMarkdown();
}

}  // namespace marglab::results_schema
