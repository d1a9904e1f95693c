#pragma once
// The results file of one run (docs/design.md §6): HDF5, written by the estimator through
// ResultsWriter, read by eigdump / tables / plots through ResultsReader, and from Python with h5py
// or pandas (tools/scripts/check_results.py validates a file independently).
//
// Schema, schema_version = 2: every root attribute, dataset and /summary attribute, with its type,
// unit and description, is one row of the tables in core/io/results_schema.{h,cpp}, over the row
// records of core/io/results_records.h; docs/design.md §6 and tools/scripts/results_schema.json
// (the Python side) are generated from them. Version 2 added /sparsify, the marg_strategy
// attribute, precision "mixed", /frontend and the frontend attribute; files of version 1 are read
// as runs with marg_strategy discard, simulated tracks and no /sparsify or /frontend rows. Not in
// the tables: RunMetadata::extra (more root strings) and the optional full priors
// /marg/priors/<k>/ (appendPriorMatrices: H_m (n,n), b_m (n), for square-root storage J_m
// (rows,n) and r_m (rows); layout_kind int32 (attribute "kind_names"), layout_frame_id int64,
// layout_offset int32, layout_dim int32, one row per variable block; attribute storage
// "sqrt"|"sq").
//
// Atomicity: the file is written under a temporary name and renamed onto the path by finish()
// (h5::File::commit). A ResultsWriter destroyed without finish() (exception, crash path) leaves
// no file at the path, so a sweep never counts an unfinished run as done. A run that fails
// numerically still calls finish() with RunStatus::kFailed and gets a complete file.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/common/eigen_types.h"
#include "core/diagnostics/diagnostics.h"
#include "core/io/hdf5.h"
#include "core/io/results_records.h"

namespace marglab {

inline constexpr int kResultsSchemaVersion = 2;

struct RunMetadata {
  std::string dataset;    // "euroc"
  std::string sequence;   // "MH_01_easy"
  std::string variant;    // "ns-qr-sqrt-f32"
  std::string precision;  // "f32" | "f64" | "mixed"
  std::string mode;       // "vo" | "vio"
  std::uint64_t seed = 0;
  std::string config_toml;
  std::string qr_threshold_mode;  // "absolute" | "relative" | "" (no flat QR)
  double qr_threshold = std::numeric_limits<double>::quiet_NaN();
  std::string marg_strategy = "discard";
  std::string frontend = "simulated";
  std::string isa;         // empty: the writer records the process's active ISA (core/linalg/isa.h)
  std::string isa_choice;  // empty: the writer records how the active ISA was chosen
  // frontend "tracks": the --tracks file as given, the sequence it records, and whether
  // --tracks-any-sequence was given ("true" | "false"); all empty for other front-ends.
  std::string tracks_file;
  std::string tracks_sequence;
  std::string tracks_any_sequence;
  std::vector<std::pair<std::string, std::string>> extra;  // more root string attributes
};

// Fills a MargRecord from the diagnostics of one event (prior_cols = eigenvalues.size()).
MargRecord makeMargRecord(std::int64_t frame_index, std::int64_t t_ns, int prior_rows,
                          const PriorDiagnostics& diagnostics);

// The full prior of one event (/marg/priors/<k>); J_m, r_m empty for squared storage.
struct StoredPrior {
  PriorLayout layout;
  MatXd H_m;
  VecXd b_m;
  MatXd J_m;
  VecXd r_m;
};

struct RunSummary {
  double wall_time_s = std::numeric_limits<double>::quiet_NaN();  // NaN: t_opt + t_marg totals
};

enum class RunStatus { kOk, kFailed };
const char* runStatusName(RunStatus status);  // "ok", "failed"

// What finish() wrote to /summary (and what ResultsReader::summary() reads).
struct SummaryValues {
  double ate_rmse = std::numeric_limits<double>::quiet_NaN();
  std::int64_t n_ate_pairs = 0;
  std::int64_t n_frames = 0;
  std::int64_t n_marg = 0;
  double duration_s = 0.0;
  double t_opt_total_s = 0.0;
  double t_marg_total_s = 0.0;
  double wall_time_s = 0.0;
  double realtime_factor = std::numeric_limits<double>::quiet_NaN();
  Eigen::Matrix3d R_gt_est = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t_gt_est = Eigen::Vector3d::Zero();
};

class ResultsWriter {
 public:
  // Starts the file (temporary name) and writes the root metadata. Throws InputError.
  static ResultsWriter create(const std::string& path, const RunMetadata& metadata);
  ResultsWriter(ResultsWriter&&) noexcept;
  ResultsWriter& operator=(ResultsWriter&&) noexcept;
  ~ResultsWriter();  // without finish(): the temporary is deleted, nothing appears at path

  void appendFrame(const FrameRecord& frame);
  void appendMarg(const MargRecord& marg);  // marg.eigenvalues becomes the next ragged row
  void appendSparsify(const SparsifyRecord& record);
  // The whole /frontend group, at most once per file (finish() writes it with zero rows if not).
  void writeFrontend(const std::vector<FrontendRecord>& rows);
  // The full double prior of marginalization event k (the /marg row of the same event); at most
  // once per k. J_m and r_m (both or neither) for square-root storage.
  void appendPriorMatrices(std::int64_t k, const PriorLayout& layout, const MatXd& H_m,
                           const VecXd& b_m, const MatXd* J_m = nullptr,
                           const VecXd* r_m = nullptr);
  // Computes ATE and the /summary attributes, writes /frames/ate_error and the status, then
  // commits (atomic rename). The writer is closed afterwards (appends throw).
  SummaryValues finish(const RunSummary& summary, RunStatus status = RunStatus::kOk,
                       std::int64_t failure_frame = -1, const std::string& failure_reason = "",
                       const std::string& failure_kind = "numerical");

  std::size_t frameCount() const;
  std::size_t margCount() const;
  const std::string& path() const;

 private:
  struct Impl;
  explicit ResultsWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

struct RunInfo {
  std::int64_t schema_version = 0;
  std::string marglab_version;
  std::string git_sha;
  std::string created_utc;
  RunMetadata metadata;
  std::string status;  // "ok" | "failed"
  std::int64_t failure_frame = -1;
  std::string failure_reason;
  std::string failure_kind;  // "" when ok
};

struct FrameColumns {
  std::vector<std::int64_t> t_ns;
  std::vector<std::uint8_t> is_keyframe;
  std::vector<std::int32_t> n_landmarks, n_observations, lm_iterations;
  std::vector<double> cost_initial, cost_final, t_opt_s, t_marg_s, ate_error;
  std::vector<Eigen::Vector3d> p_est, p_gt;
  std::vector<Eigen::Quaterniond> q_est;
  std::size_t size() const { return t_ns.size(); }
};

// Read access; every failure (missing file, not a results file, newer schema, missing object)
// throws InputError naming the file. A results file is a user's input: the constructor first
// reads in a child process (core/io/hdf5_trust.h) what the scope allows, so a file libhdf5 does
// not survive, or with any part of that unreadable, is refused there.
class ResultsReader {
 public:
  // kSummary: the root attributes (info()) and summary() — what `tables` and a sweep's resume
  // read of each run, at a fraction of the cost of the whole file; kEverything: any read below.
  // A read beyond the scope is a std::logic_error: the child would not have made it first.
  enum class Scope { kSummary, kEverything };
  explicit ResultsReader(const std::string& path, Scope scope = Scope::kEverything);
  const std::string& path() const { return path_; }
  const RunInfo& info() const { return info_; }
  std::vector<FrameRecord> frameRecords() const;
  FrameColumns frames() const;  // the same rows as columns
  std::size_t margCount() const;
  std::vector<MargRecord> margs(bool with_eigenvalues = true) const;
  MargRecord marg(std::size_t k) const;  // with eigenvalues; InputError when k ≥ margCount()
  VecXd eigenvalues(std::size_t k) const;
  // /sparsify rows (empty for files without the group).
  std::vector<SparsifyRecord> sparsifyRecords() const;
  // /frontend rows (empty for files without the group).
  std::vector<FrontendRecord> frontendRecords() const;
  std::vector<std::int64_t> storedPriors() const;  // ascending event indices
  std::optional<StoredPrior> prior(std::int64_t k) const;
  SummaryValues summary() const;
  const h5::File& file() const { return file_; }

 private:
  struct Unchecked {};
  ResultsReader(const std::string& path, Unchecked);  // without the child (the child's reader)
  void open();
  void requireEverything() const;
  std::string path_;
  Scope scope_ = Scope::kEverything;
  h5::File file_;
  RunInfo info_;
};

}  // namespace marglab
