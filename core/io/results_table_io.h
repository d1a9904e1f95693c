#pragma once
// Reading and writing the tables of core/io/results_schema.h: a column's HDF5 type, shape and
// attributes come from its record member's C++ type (Stored<T>), so ResultsWriter and
// ResultsReader loop over the tables instead of naming datasets. Internal to core/io.

#include <fmt/format.h>

#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "core/common/error.h"
#include "core/io/hdf5.h"
#include "core/io/results_schema.h"

namespace marglab::results_schema {

// The writer of one column: an extendible dataset of its element type, or a ragged group.
using ColumnWriter =
    std::variant<h5::Appendable<std::int64_t>, h5::Appendable<std::int32_t>,
                 h5::Appendable<std::uint8_t>, h5::Appendable<double>, h5::RaggedWriter<double>>;

inline void describe(const h5::Object& o, const char* unit, const char* description) {
  o.setAttr("units", unit);
  o.setAttr("description", description);
}

template <class T>
ColumnWriter createColumn(const h5::Group& g, const char* name, const char* unit,
                          const char* description) {
  using S = typename Stored<T>::type;
  constexpr int kWidth = Stored<T>::kWidth;
  if constexpr (kWidth == kRagged) {
    h5::RaggedWriter<S> w(g, name);
    w.group().setAttr("description", description);
    return w;
  } else {
    h5::Appendable<S> w =
        kWidth == 0 ? h5::appendable<S>(g, name) : h5::appendableRows<S>(g, name, kWidth);
    describe(w.dataset(), unit, description);
    if constexpr (std::is_same_v<T, Eigen::Quaterniond>) w.dataset().setAttr("order", "x y z w");
    if constexpr (std::is_same_v<T, Vec7d>) {
      w.dataset().setAttr("columns", std::vector<std::string>(kGaugeDirectionNames.begin(),
                                                              kGaugeDirectionNames.end()));
    }
    return w;
  }
}

inline void appendValue(ColumnWriter& w, std::int64_t v) {
  std::get<h5::Appendable<std::int64_t>>(w).append(v);
}
inline void appendValue(ColumnWriter& w, int v) {
  std::get<h5::Appendable<std::int32_t>>(w).append(v);
}
inline void appendValue(ColumnWriter& w, bool v) {
  std::get<h5::Appendable<std::uint8_t>>(w).append(static_cast<std::uint8_t>(v ? 1 : 0));
}
inline void appendValue(ColumnWriter& w, double v) {
  std::get<h5::Appendable<double>>(w).append(v);
}
inline void appendValue(ColumnWriter& w, const Eigen::Quaterniond& q) {
  std::get<h5::Appendable<double>>(w).append({q.x(), q.y(), q.z(), q.w()});
}
template <class Derived>
void appendValue(ColumnWriter& w, const Eigen::MatrixBase<Derived>& v) {
  if constexpr (Derived::RowsAtCompileTime == Eigen::Dynamic) {
    std::get<h5::RaggedWriter<double>>(w).append(v);
  } else {
    std::get<h5::Appendable<double>>(w).append(v);
  }
}

// The group of a table and one writer per column, in table order.
template <class Record>
class TableWriter {
 public:
  TableWriter() = default;
  TableWriter(const h5::Group& parent, const Table<Record>& table) : table_(&table) {
    const h5::Group g = parent.group(table.group);
    g.setAttr("description", table.description);
    for (const Column<Record>& c : table.columns) {
      columns_.push_back(std::visit(
          [&](auto member) {
            return createColumn<MemberType<decltype(member)>>(g, c.name, c.unit, c.description);
          },
          c.member));
    }
  }
  // Appends the kAppend columns of r (kFinish ones are filled through column()).
  void append(const Record& r) {
    for (std::size_t i = 0; i < columns_.size(); ++i) {
      const Column<Record>& c = table_->columns[i];
      if (c.origin == Origin::kFinish) continue;
      std::visit([&](auto member) { appendValue(columns_[i], r.*member); }, c.member);
    }
  }
  template <class Writer>
  Writer& column(const std::string& name) {
    for (std::size_t i = 0; i < columns_.size(); ++i) {
      if (name == table_->columns[i].name) return std::get<Writer>(columns_[i]);
    }
    throw std::logic_error("results schema: no column /" + std::string(table_->group) + "/" + name);
  }

 private:
  const Table<Record>* table_ = nullptr;
  std::vector<ColumnWriter> columns_;
};

// ---- reading ------------------------------------------------------------------------------------

// Whether to read the ragged columns (the eigenvalues: the bulk of a file).
enum class RaggedColumns { kRead, kSkip };

// Rows [first, first + count) of the column `name` into out[0 .. count) (out.size() == count);
// every column must have `rows` rows.
template <class Record, class T>
void readColumn(const h5::Group& g, const char* name, T Record::*member, std::size_t first,
                std::vector<Record>& out, std::size_t rows, RaggedColumns ragged) {
  using S = typename Stored<T>::type;
  constexpr int kWidth = Stored<T>::kWidth;
  const std::size_t count = out.size();
  const auto bad = [&](const std::string& what) {
    return InputError(g.fileName(), 0, fmt::format("{}/{}: {}", g.path(), name, what));
  };
  if constexpr (kWidth == kRagged) {
    if (ragged == RaggedColumns::kSkip) return;
    const h5::RaggedReader<S> reader(g, name);
    if (reader.rows() != rows) throw bad(fmt::format("{} rows, expected {}", reader.rows(), rows));
    for (std::size_t k = 0; k < count; ++k) {
      const std::vector<S> v = reader.row(first + k);
      out[k].*member = Eigen::Map<const VecXd>(v.data(), static_cast<Eigen::Index>(v.size()));
    }
  } else {
    const h5::Dataset d = g.openDataset(name);
    const std::vector<hsize_t> shape = d.shape();
    const std::vector<hsize_t> expected =
        kWidth == 0 ? std::vector<hsize_t>{rows} : std::vector<hsize_t>{rows, hsize_t{kWidth}};
    if (shape != expected) {
      throw bad(fmt::format("shape ({}), expected ({}) (columns differ in length or width)",
                            fmt::join(shape, ", "), fmt::join(expected, ", ")));
    }
    const std::vector<S> v = d.readRows<S>(first, count);
    for (std::size_t k = 0; k < count; ++k) {
      if constexpr (kWidth == 0) {
        out[k].*member = static_cast<T>(v[k]);
      } else if constexpr (std::is_same_v<T, Eigen::Quaterniond>) {
        const S* q = &v[4 * k];  // stored x y z w
        out[k].*member = Eigen::Quaterniond(q[3], q[0], q[1], q[2]);
      } else {
        out[k].*member = Eigen::Map<const T>(&v[static_cast<std::size_t>(kWidth) * k]);
      }
    }
  }
}

// Rows [first, first + count) of a table; count = npos: to the end. kOptional columns absent
// from the file keep the record's default.
template <class Record>
std::vector<Record> readTable(const h5::Group& g, const Table<Record>& table,
                              RaggedColumns ragged = RaggedColumns::kRead, std::size_t first = 0,
                              std::size_t count = std::string::npos) {
  const std::size_t rows =
      static_cast<std::size_t>(g.openDataset(table.columns.front().name).shape().at(0));
  if (count == std::string::npos) count = rows - std::min(first, rows);
  std::vector<Record> out(count);
  for (const Column<Record>& c : table.columns) {
    if (c.presence == Presence::kOptional && !g.exists(c.name)) continue;
    std::visit([&](auto member) { readColumn(g, c.name, member, first, out, rows, ragged); },
               c.member);
  }
  return out;
}

}  // namespace marglab::results_schema
