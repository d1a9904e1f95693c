// The papers' values (experiments/paper_values.toml) that the tables print beside ours.

#include "core/experiment/tables.h"

#include <fmt/core.h>

#include <toml++/toml.h>
#include <utility>

#include "core/common/error.h"
#include "core/common/source_dir.h"

namespace marglab::experiment {

namespace {

int lineOf(const toml::node& node) { return static_cast<int>(node.source().begin.line); }

}  // namespace

const PaperTable::Row* PaperTable::row(const std::string& key) const {
  for (const Row& r : rows) {
    if (r.key == key) return &r;
  }
  return nullptr;
}

std::string defaultPaperValuesPath() {
  return std::string(sourceDir()) + "/experiments/paper_values.toml";
}

PaperValues loadPaperValues(const std::string& path) {
  toml::table root;
  try {
    root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    throw InputError(path, static_cast<int>(e.source().begin.line), std::string(e.description()));
  }
  PaperValues values;
  values.file = path;
  values.source = root["source"].value_or(std::string());
  for (const auto& [key, node] : root) {
    const std::string id(key.str());
    if (id == "source") continue;
    const toml::table* table = node.as_table();
    const auto starts = [&id](const char* prefix) { return id.rfind(prefix, 0) == 0; };
    if (table == nullptr ||
        !(starts("table") || starts("sparsify_table") || starts("massspring_table"))) {
      throw InputError(
          path, lineOf(node),
          "expected source = \"...\" or [tableN] / [sparsify_tableN] / [massspring_tableN] tables");
    }
    PaperTable t;
    t.id = id;
    t.source = (*table)["source"].value_or(std::string());
    t.paper = (*table)["paper"].value_or(std::string());
    for (const char* list : {"columns", "quantities"}) {
      const toml::array* array = (*table)[list].as_array();
      if (array == nullptr || array->empty()) {
        throw InputError(path, lineOf(*table), fmt::format("[{}] needs {} = [...]", id, list));
      }
      for (const toml::node& item : *array) {
        if (!item.is_string()) throw InputError(path, lineOf(item), "expected a string");
        (std::string(list) == "columns" ? t.columns : t.quantities).push_back(**item.as_string());
      }
    }
    const toml::array* rows = (*table)["row"].as_array();
    if (rows == nullptr) throw InputError(path, lineOf(*table), "[" + id + "] needs row = [...]");
    for (const toml::node& row_node : *rows) {
      const toml::table* row = row_node.as_table();
      if (row == nullptr) throw InputError(path, lineOf(row_node), "a row must be a table");
      PaperTable::Row r;
      r.key = (*row)["dataset"].value_or((*row)["metric"].value_or(std::string()));
      r.label = (*row)["label"].value_or(r.key);
      if (r.key.empty()) {
        throw InputError(path, lineOf(row_node),
                         "a row needs dataset = \"...\" or metric = \"...\"");
      }
      for (const std::string& q : t.quantities) {
        const toml::array* cells = (*row)[q].as_array();
        if (cells == nullptr || cells->size() != t.columns.size()) {
          throw InputError(
              path, lineOf(row_node),
              fmt::format("row {} needs {} = [...] with {} values", r.key, q, t.columns.size()));
        }
        std::vector<PaperCell> list;
        for (const toml::node& cell : *cells) {
          PaperCell c;
          if (const auto v = cell.value<double>();
              v && (cell.is_floating_point() || cell.is_integer())) {
            c.state = PaperCell::State::kValue;
            c.value = *v;
          } else if (cell.is_string() && **cell.as_string() == "x") {
            c.state = PaperCell::State::kFailed;
          } else if (cell.is_string() && **cell.as_string() == "n/a") {
            c.state = PaperCell::State::kMissing;
          } else {
            throw InputError(path, lineOf(cell), "expected a number, \"x\" or \"n/a\"");
          }
          list.push_back(c);
        }
        r.cells[q] = std::move(list);
      }
      t.rows.push_back(std::move(r));
    }
    values.tables[id] = std::move(t);
  }
  return values;
}

}  // namespace marglab::experiment
