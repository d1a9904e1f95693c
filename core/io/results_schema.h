#pragma once
// The results-file schema (docs/design.md §6), defined once: one table row per root attribute,
// per dataset of /frames, /marg, /sparsify, /frontend and per /summary attribute. Everything that
// knows the schema derives from these tables:
//   ResultsWriter   creates, describes (units, description) and appends the datasets, writes the
//                   attributes (core/io/results_file.cpp)
//   ResultsReader   reads them, requires the kRequired ones, keeps unknown root strings as extra
//   schemaJson()    tools/scripts/results_schema.json, from which the Python reader
//                   (marglab_results.py) and check_results.py take every name; `marglab schema
//                   --json` prints it, test/io checks the file is current
//   schemaMarkdown() the tables of docs/design.md §6 (`marglab schema --markdown`, checked too)
//
// A dataset's stored type and shape follow from the C++ type of its record member:
//   std::int64_t → int64 (n)     int → int32 (n)     bool → uint8 (n, 0 | 1)     double → f64 (n)
//   Eigen::Vector3d → f64 (n,3)  Eigen::Quaterniond → f64 (n,4) x y z w (attribute "order")
//   Vec7d → f64 (n,7) along kGaugeDirectionNames (attribute "columns")
//   VecXd → ragged group {values f64 [K], offsets int64 [n+1]} (h5::RaggedWriter)
// so adding a column is adding the record member and one row to its table.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/diagnostics/gauge.h"
#include "core/io/results_file.h"

namespace marglab::results_schema {

// kOptional: absent in files written before the item existed; the reader then keeps the record's
// default (documented at the member).
enum class Presence { kRequired, kOptional };
// kAppend: written by the append call of its record (create() for attributes); kFinish: computed
// and written by finish().
enum class Origin { kAppend, kFinish };

// How a record member is stored: element type, row width (0: one value per row) and, for rows,
// the names of its columns; kRagged: a ragged group (VecXd).
inline constexpr int kRagged = -1;
template <class T>
struct Stored;
template <>
struct Stored<std::int64_t> {
  using type = std::int64_t;
  static constexpr int kWidth = 0;
};
template <>
struct Stored<int> {
  using type = std::int32_t;
  static constexpr int kWidth = 0;
};
template <>
struct Stored<bool> {
  using type = std::uint8_t;
  static constexpr int kWidth = 0;
};
template <>
struct Stored<double> {
  using type = double;
  static constexpr int kWidth = 0;
};
template <>
struct Stored<Eigen::Vector3d> {
  using type = double;
  static constexpr int kWidth = 3;
};
template <>
struct Stored<Eigen::Quaterniond> {
  using type = double;
  static constexpr int kWidth = 4;
};
template <>
struct Stored<Vec7d> {
  using type = double;
  static constexpr int kWidth = kNumGaugeDirections;
};
template <>
struct Stored<VecXd> {
  using type = double;
  static constexpr int kWidth = kRagged;
};

// The member type T of a pointer to member T Record::*.
template <class Pointer>
struct MemberOf;
template <class T, class Record>
struct MemberOf<T Record::*> {
  using type = T;
};
template <class Pointer>
using MemberType = typename MemberOf<Pointer>::type;

template <class Record>
using Member = std::variant<std::int64_t Record::*, int Record::*, bool Record::*, double Record::*,
                            Eigen::Vector3d Record::*, Eigen::Quaterniond Record::*,
                            Vec7d Record::*, VecXd Record::*>;

template <class Record>
struct Column {
  const char* name;
  const char* unit;  // "1" for counts and dimensionless values
  const char* description;
  Member<Record> member;
  Presence presence = Presence::kRequired;
  Origin origin = Origin::kAppend;
};

// One group of row-aligned datasets (/frames, /marg, ...): row k of every column is record k.
template <class Record>
struct Table {
  const char* group;        // "frames"
  const char* description;  // the group's "description" attribute
  std::vector<Column<Record>> columns;
};

const Table<FrameRecord>& frameTable();
const Table<MargRecord>& margTable();
const Table<SparsifyRecord>& sparsifyTable();
const Table<FrontendRecord>& frontendTable();

// Root attributes: members of RunInfo, or of its RunMetadata.
using AttributeMember =
    std::variant<std::string RunInfo::*, std::int64_t RunInfo::*, std::string RunMetadata::*,
                 std::uint64_t RunMetadata::*, double RunMetadata::*>;

struct Attribute {
  const char* name;
  const char* description;
  AttributeMember member;
  std::vector<const char*> values = {};  // the allowed values of a string; empty: any
  Presence presence = Presence::kRequired;
  // kFinish: the run's outcome, written provisionally by create() and finally by finish().
  Origin origin = Origin::kAppend;
};
const std::vector<Attribute>& rootAttributes();

// /summary attributes (written by finish()): Matrix3d as f64[9] row-major, Vector3d as f64[3].
using SummaryMember =
    std::variant<double SummaryValues::*, std::int64_t SummaryValues::*,
                 Eigen::Matrix3d SummaryValues::*, Eigen::Vector3d SummaryValues::*>;

struct SummaryAttribute {
  const char* name;
  const char* unit;
  const char* description;
  SummaryMember member;
};
const std::vector<SummaryAttribute>& summaryAttributes();

// The schema versions the reader accepts (1 .. kResultsSchemaVersion).
std::vector<int> readableVersions();

// The whole schema as JSON (tools/scripts/results_schema.json) and as the Markdown tables of
// docs/design.md §6; both end with a newline.
std::string schemaJson();
std::string schemaMarkdown();

}  // namespace marglab::results_schema
