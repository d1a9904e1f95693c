// The results schema defined once (core/io/results_schema.h): the committed JSON the Python reader
// loads and the design doc's tables are what the tables generate, the writer creates exactly the
// tables' datasets and attributes, and the reader round-trips every column through them.

#include "core/io/results_schema.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/io/results_file.h"

namespace marglab {
namespace {

using test::CliResult;
using test::runCli;
using test::runShell;

std::string readSource(const std::string& relative) {
  std::ifstream in(std::string(sourceDir()) + "/" + relative);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(ResultsSchema, CommittedJsonIsCurrent) {
  EXPECT_EQ(readSource("tools/scripts/results_schema.json"), results_schema::schemaJson())
      << "regenerate: build/bin/marglab schema --json > tools/scripts/results_schema.json";
}

TEST(ResultsSchema, DesignDocTablesAreCurrent) {
  const std::string doc = readSource("docs/design.md");
  const std::string begin = "<!-- BEGIN schema tables";
  const std::string end = "<!-- END schema tables -->";
  const std::size_t a = doc.find('\n', doc.find(begin));
  const std::size_t b = doc.find(end);
  ASSERT_NE(doc.find(begin), std::string::npos);
  ASSERT_NE(b, std::string::npos);
  EXPECT_EQ(doc.substr(a + 1, b - a - 1), results_schema::schemaMarkdown())
      << "regenerate the block of docs/design.md §6 with build/bin/marglab schema --markdown";
}

TEST(ResultsSchema, CliPrintsTheSchema) {
  const CliResult json = runCli("schema --json");
  EXPECT_EQ(json.exit_code, 0);
  EXPECT_EQ(json.output, results_schema::schemaJson());
  EXPECT_EQ(runCli("schema --markdown").output, results_schema::schemaMarkdown());
}

template <class Record>
std::set<std::string> tableNames(const results_schema::Table<Record>& table) {
  std::set<std::string> names;
  for (const auto& c : table.columns) names.insert(c.name);
  return names;
}

class ResultsSchemaFile : public test::TempDirTest {};

// What the writer creates is the tables, nothing more or less.
TEST_F(ResultsSchemaFile, WriterCreatesExactlyTheTables) {
  const std::string path = temp_.file("run.h5");
  ResultsWriter w = ResultsWriter::create(path, RunMetadata{});
  w.appendFrame(FrameRecord{});
  w.finish({});
  const ResultsReader r(path);
  const h5::File& f = r.file();
  const auto members = [&](const char* group) {
    const auto v = f.openGroup(group).members();
    return std::set<std::string>(v.begin(), v.end());
  };
  EXPECT_EQ(members("frames"), tableNames(results_schema::frameTable()));
  EXPECT_EQ(members("marg"), tableNames(results_schema::margTable()));
  EXPECT_EQ(members("sparsify"), tableNames(results_schema::sparsifyTable()));
  EXPECT_EQ(members("frontend"), tableNames(results_schema::frontendTable()));
  std::set<std::string> root, expected;
  for (const std::string& name : f.attrNames()) root.insert(name);
  for (const auto& a : results_schema::rootAttributes()) expected.insert(a.name);
  EXPECT_EQ(root, expected);
  std::set<std::string> summary, expected_summary;
  for (const std::string& name : f.openGroup("summary").attrNames()) summary.insert(name);
  for (const auto& a : results_schema::summaryAttributes()) expected_summary.insert(a.name);
  EXPECT_EQ(summary, expected_summary);
}

// The value of the column at position i of a table: different from the member's default and from
// the other columns of its type, so that a column written from another member, from a default or
// not at all reads back different.
void setDistinct(std::int64_t& v, int i) { v = 1'000'000'000'000LL + i; }
void setDistinct(int& v, int i) { v = 1000 + i; }
void setDistinct(bool& v, int) { v = true; }  // one bool per table
void setDistinct(double& v, int i) { v = 0.25 + i; }
void setDistinct(Eigen::Vector3d& v, int i) { v = Eigen::Vector3d(i + 1.5, -i - 2.5, 0.5 * i + 3); }
void setDistinct(Eigen::Quaterniond& q, int i) {
  q = Eigen::AngleAxisd(0.1 * (i + 1), Eigen::Vector3d(1, 2, 3).normalized());
}
void setDistinct(Vec7d& v, int i) { v = Vec7d::LinSpaced(i + 1.5, i + 7.5); }
void setDistinct(VecXd& v, int i) { v = VecXd::LinSpaced(i + 2, -1.5, 2.5 + i); }

template <class T>
T distinctValue(int i) {
  T v;
  setDistinct(v, i);
  return v;
}

// Equal in every coefficient (the distinct values have no NaN).
template <class T>
bool same(const T& a, const T& b) {
  if constexpr (std::is_same_v<T, Eigen::Quaterniond>) {
    return a.coeffs() == b.coeffs();
  } else if constexpr (std::is_base_of_v<Eigen::MatrixBase<T>, T>) {
    return a.size() == b.size() && a == b;
  } else {
    return a == b;
  }
}

// A record with its column's distinct value in every member of its table.
template <class Record>
Record distinctRecord(const results_schema::Table<Record>& table) {
  Record r;
  for (std::size_t i = 0; i < table.columns.size(); ++i) {
    std::visit([&](auto member) { setDistinct(r.*member, static_cast<int>(i)); },
               table.columns[i].member);
  }
  return r;
}

// The one row read back holds each column's distinct value in the column's member, for every
// column the append call writes (finish() computes the others). Two columns on one member fail
// too: the member holds one value only.
template <class Record>
void expectDistinctRow(const results_schema::Table<Record>& table,
                       const std::vector<Record>& read) {
  ASSERT_EQ(read.size(), 1u) << table.group;
  for (std::size_t i = 0; i < table.columns.size(); ++i) {
    const results_schema::Column<Record>& c = table.columns[i];
    if (c.origin == results_schema::Origin::kFinish) continue;
    std::visit(
        [&](auto member) {
          using T = results_schema::MemberType<decltype(member)>;
          EXPECT_TRUE(same(distinctValue<T>(static_cast<int>(i)), read[0].*member))
              << table.group << "/" << c.name;
        },
        c.member);
  }
}

// The records are the schema's only source: a column of any table is its record member, written
// by the record's append call and read back into the same member.
TEST_F(ResultsSchemaFile, EveryColumnRoundTripsFromItsRecord) {
  const std::string path = temp_.file("run.h5");
  ResultsWriter w = ResultsWriter::create(path, RunMetadata{});
  w.appendFrame(distinctRecord(results_schema::frameTable()));
  w.appendMarg(distinctRecord(results_schema::margTable()));
  w.appendSparsify(distinctRecord(results_schema::sparsifyTable()));
  w.writeFrontend({distinctRecord(results_schema::frontendTable())});
  w.finish({});
  const ResultsReader r(path);
  expectDistinctRow(results_schema::frameTable(), r.frameRecords());
  expectDistinctRow(results_schema::margTable(), r.margs());
  expectDistinctRow(results_schema::sparsifyTable(), r.sparsifyRecords());
  expectDistinctRow(results_schema::frontendTable(), r.frontendRecords());
}

// A required column missing from a file is an InputError naming it; an optional one keeps the
// record's default.
TEST_F(ResultsSchemaFile, ReaderRequiresRequiredColumnsOnly) {
  const std::string path = temp_.file("run.h5");
  ResultsWriter w = ResultsWriter::create(path, RunMetadata{});
  SparsifyRecord s;
  s.kld = 0.5;
  w.appendSparsify(s);
  w.finish({});
  const std::string edit =
      "/usr/bin/python3 -c \"import h5py; f = h5py.File('" + path +
      "', 'r+'); del f['sparsify/info_dense']; del f['sparsify/info_sparse']\"";
  if (runShell(edit).exit_code != 0) GTEST_SKIP() << "no /usr/bin/python3 with h5py";
  const std::vector<SparsifyRecord> rows = ResultsReader(path).sparsifyRecords();
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].kld, 0.5);
  EXPECT_TRUE(rows[0].info_dense.array().isNaN().all());

  runShell("/usr/bin/python3 -c \"import h5py; f = h5py.File('" + path +
           "', 'r+'); del f['sparsify/kld']\"");
  try {
    ResultsReader(path).sparsifyRecords();
    FAIL() << "a missing required column was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("kld"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace marglab
