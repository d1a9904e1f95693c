#include "core/io/results_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>

#include "core/common/error.h"
#include "core/common/utc_time.h"
#include "core/diagnostics/ate.h"
#include "core/io/hdf5_trust.h"
#include "core/io/results_schema.h"
#include "core/io/results_table_io.h"
#include "core/linalg/isa.h"
#include "marglab/version.h"

namespace marglab {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::vector<std::string> kindNames() {
  std::vector<std::string> names;
  for (int k = 0; k < 4; ++k)
    names.emplace_back(variableKindName(static_cast<PriorVariableKind>(k)));
  return names;
}

}  // namespace

const char* runStatusName(RunStatus status) { return status == RunStatus::kOk ? "ok" : "failed"; }

MargRecord makeMargRecord(std::int64_t frame_index, std::int64_t t_ns, int prior_rows,
                          const PriorDiagnostics& diagnostics) {
  MargRecord m;
  m.frame_index = frame_index;
  m.t_ns = t_ns;
  m.prior_cols = static_cast<int>(diagnostics.spectrum.eigenvalues.size());
  m.prior_rows = prior_rows;
  m.rank = diagnostics.spectrum.rank;
  m.n_negative = diagnostics.spectrum.n_negative;
  m.sigma_min = diagnostics.spectrum.sigma_min;
  m.sigma_max = diagnostics.spectrum.sigma_max;
  m.eig_tolerance = diagnostics.spectrum.tolerance;
  m.dEm = diagnostics.dEm;
  m.eigenvalues = diagnostics.spectrum.eigenvalues;
  return m;
}

// ---- attributes ---------------------------------------------------------------------------

namespace {

using results_schema::Attribute;
using results_schema::Origin;
using results_schema::Presence;
using results_schema::SummaryAttribute;

// A root attribute's value in a RunInfo (its own members and its metadata's).
template <class T>
T& valueIn(RunInfo& info, T RunInfo::*member) {
  return info.*member;
}
template <class T>
T& valueIn(RunInfo& info, T RunMetadata::*member) {
  return info.metadata.*member;
}

// The seed is stored as the int64 with its bit pattern; everything else as it is.
template <class T>
using StoredAttribute = std::conditional_t<std::is_same_v<T, std::uint64_t>, std::int64_t, T>;

void writeAttribute(const h5::Object& o, const Attribute& a, RunInfo& info) {
  std::visit(
      [&](auto member) {
        const auto& value = valueIn(info, member);
        o.setAttr(a.name, static_cast<StoredAttribute<std::decay_t<decltype(value)>>>(value));
      },
      a.member);
}

void readAttribute(const h5::File& f, const Attribute& a, RunInfo& info) {
  if (!f.hasAttr(a.name)) {
    if (a.presence == Presence::kOptional) return;  // an older file: the RunInfo default
    throw InputError(f.path(), 0, fmt::format("missing root attribute {}", a.name));
  }
  std::visit(
      [&](auto member) {
        auto& value = valueIn(info, member);
        using T = std::decay_t<decltype(value)>;
        value = static_cast<T>(f.attr<StoredAttribute<T>>(a.name));
      },
      a.member);
}

bool isSchemaAttribute(const std::string& name) {
  const auto& all = results_schema::rootAttributes();
  return std::any_of(all.begin(), all.end(), [&](const Attribute& a) { return name == a.name; });
}

// /summary: Matrix3d as f64[9] row-major, Vector3d as f64[3].
void writeSummary(const h5::Group& g, const SummaryValues& s) {
  for (const SummaryAttribute& a : results_schema::summaryAttributes()) {
    std::visit(
        [&](auto member) {
          using T = results_schema::MemberType<decltype(member)>;
          if constexpr (std::is_arithmetic_v<T>) {
            g.setAttr(a.name, s.*member);
          } else {
            const Eigen::Matrix<double, T::ColsAtCompileTime, T::RowsAtCompileTime> rows =
                (s.*member).transpose();  // column-major storage of the transpose: row-major
            g.setAttr(a.name, std::vector<double>(rows.data(), rows.data() + rows.size()));
          }
        },
        a.member);
  }
}

SummaryValues readSummary(const h5::Group& g, const std::string& path) {
  SummaryValues s;
  for (const SummaryAttribute& a : results_schema::summaryAttributes()) {
    std::visit(
        [&](auto member) {
          using T = results_schema::MemberType<decltype(member)>;
          if constexpr (std::is_arithmetic_v<T>) {
            s.*member = g.attr<T>(a.name);
          } else {
            const auto v = g.attr<std::vector<double>>(a.name);
            if (v.size() != static_cast<std::size_t>(T::SizeAtCompileTime)) {
              throw InputError(path, 0,
                               fmt::format("/summary: {} has {} values, expected {}", a.name,
                                           v.size(), T::SizeAtCompileTime));
            }
            s.*member =
                Eigen::Map<const Eigen::Matrix<double, T::ColsAtCompileTime, T::RowsAtCompileTime>>(
                    v.data())
                    .transpose();
          }
        },
        a.member);
  }
  return s;
}

}  // namespace

// ---- writer ---------------------------------------------------------------------------------

struct ResultsWriter::Impl {
  h5::File file;
  bool open = true;
  RunInfo info;  // the root attributes (outcome provisional until finish())
  results_schema::TableWriter<FrameRecord> frames;
  results_schema::TableWriter<MargRecord> marg;
  results_schema::TableWriter<SparsifyRecord> sparsify;
  results_schema::TableWriter<FrontendRecord> frontend;
  // kept for finish()
  std::vector<std::int64_t> frame_t_ns;
  std::vector<Eigen::Vector3d> frame_p_est, frame_p_gt;
  double t_opt_total = 0.0, t_marg_total = 0.0;
  std::size_t marg_rows = 0;
  bool frontend_written = false;

  void requireOpen() const {
    if (!open) throw InputError(file.path(), 0, "results file already finished");
  }
};

ResultsWriter::ResultsWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ResultsWriter::ResultsWriter(ResultsWriter&&) noexcept = default;
ResultsWriter& ResultsWriter::operator=(ResultsWriter&&) noexcept = default;
ResultsWriter::~ResultsWriter() = default;

ResultsWriter ResultsWriter::create(const std::string& path, const RunMetadata& metadata) {
  auto d = std::make_unique<Impl>();
  d->file = h5::File::create(path);
  RunInfo& info = d->info;
  info.schema_version = kResultsSchemaVersion;
  info.marglab_version = MARGLAB_VERSION_STRING;
  info.git_sha = MARGLAB_GIT_SHA;
  info.created_utc = utcNowIso8601();
  info.metadata = metadata;
  if (info.metadata.isa.empty()) info.metadata.isa = isaName(activeIsa());
  if (info.metadata.isa_choice.empty()) info.metadata.isa_choice = activeIsaChoice();
  // Provisional outcome: replaced by finish(); only visible if someone inspects the temporary.
  info.status = "running";
  for (const Attribute& a : results_schema::rootAttributes()) writeAttribute(d->file, a, info);
  for (const auto& [key, value] : metadata.extra) d->file.setAttr(key, value);

  d->frames = {d->file, results_schema::frameTable()};
  d->marg = {d->file, results_schema::margTable()};
  // Created for every run, so that a reader of a discard run sees zero rows, not a missing group.
  d->sparsify = {d->file, results_schema::sparsifyTable()};
  return ResultsWriter(std::move(d));
}

void ResultsWriter::appendFrame(const FrameRecord& r) {
  Impl& d = *impl_;
  d.requireOpen();
  d.frames.append(r);
  d.frame_t_ns.push_back(r.t_ns);
  d.frame_p_est.push_back(r.p_est);
  d.frame_p_gt.push_back(r.p_gt);
  d.t_opt_total += r.t_opt_s;
  d.t_marg_total += r.t_marg_s;
}

void ResultsWriter::appendMarg(const MargRecord& m) {
  Impl& d = *impl_;
  d.requireOpen();
  d.marg.append(m);
  ++d.marg_rows;
}

void ResultsWriter::appendSparsify(const SparsifyRecord& r) {
  Impl& d = *impl_;
  d.requireOpen();
  d.sparsify.append(r);
}

void ResultsWriter::writeFrontend(const std::vector<FrontendRecord>& rows) {
  Impl& d = *impl_;
  d.requireOpen();
  if (d.frontend_written) throw InputError(d.file.path(), 0, "/frontend written twice");
  d.frontend_written = true;
  d.frontend = {d.file, results_schema::frontendTable()};
  for (const FrontendRecord& r : rows) d.frontend.append(r);
}

void ResultsWriter::appendPriorMatrices(std::int64_t k, const PriorLayout& layout, const MatXd& H_m,
                                        const VecXd& b_m, const MatXd* J_m, const VecXd* r_m) {
  Impl& d = *impl_;
  d.requireOpen();
  const std::string where = fmt::format("/marg/priors/{}", k);
  if (k < 0) throw std::invalid_argument("appendPriorMatrices: negative event index");
  if ((J_m == nullptr) != (r_m == nullptr)) {
    throw std::invalid_argument("appendPriorMatrices: pass both J_m and r_m or neither");
  }
  const Eigen::Index n = H_m.rows();
  if (H_m.cols() != n || b_m.size() != n || layoutDimension(layout) > n ||
      (J_m != nullptr && (J_m->cols() != n || r_m->size() != J_m->rows()))) {
    throw std::invalid_argument("appendPriorMatrices: dimension mismatch for " + where);
  }
  if (d.file.exists(where))
    throw std::invalid_argument("appendPriorMatrices: " + where + " exists");
  const h5::Group g = d.file.group(where);
  g.setAttr("storage", J_m != nullptr ? "sqrt" : "sq");
  g.writeMatrix("H_m", H_m);
  g.write("b_m", std::vector<double>(b_m.data(), b_m.data() + b_m.size()));
  if (J_m != nullptr) {
    g.writeMatrix("J_m", *J_m);
    g.write("r_m", std::vector<double>(r_m->data(), r_m->data() + r_m->size()));
  }
  std::vector<std::int32_t> kind, offset, dim;
  std::vector<std::int64_t> frame_id;
  for (const PriorVariable& v : layout) {
    kind.push_back(static_cast<std::int32_t>(v.kind));
    frame_id.push_back(v.frame_id);
    offset.push_back(v.offset);
    dim.push_back(variableDimension(v.kind));
  }
  g.write("layout_kind", kind).setAttr("kind_names", kindNames());
  g.write("layout_frame_id", frame_id);
  g.write("layout_offset", offset);
  g.write("layout_dim", dim);
}

SummaryValues ResultsWriter::finish(const RunSummary& summary, RunStatus status,
                                    std::int64_t failure_frame, const std::string& failure_reason,
                                    const std::string& failure_kind) {
  Impl& d = *impl_;
  d.requireOpen();
  // Every file has the group (zero rows when the writer's user had no front-end statistics).
  if (!d.frontend_written) writeFrontend({});
  const AteResult ate = computeAte(d.frame_p_est, d.frame_p_gt);
  d.frames.column<h5::Appendable<double>>("ate_error").append(ate.error);

  SummaryValues s;
  s.ate_rmse = ate.rmse;
  s.n_ate_pairs = static_cast<std::int64_t>(ate.n_pairs);
  s.n_frames = static_cast<std::int64_t>(d.frame_t_ns.size());
  s.n_marg = static_cast<std::int64_t>(d.marg_rows);
  s.duration_s = d.frame_t_ns.empty()
                     ? 0.0
                     : static_cast<double>(d.frame_t_ns.back() - d.frame_t_ns.front()) * 1e-9;
  s.t_opt_total_s = d.t_opt_total;
  s.t_marg_total_s = d.t_marg_total;
  s.wall_time_s =
      std::isfinite(summary.wall_time_s) ? summary.wall_time_s : d.t_opt_total + d.t_marg_total;
  s.realtime_factor = s.wall_time_s > 0.0 ? s.duration_s / s.wall_time_s : kNaN;
  s.R_gt_est = ate.alignment.R_gt_est;
  s.t_gt_est = ate.alignment.t_gt_est;
  writeSummary(d.file.group("summary"), s);

  const bool ok = status == RunStatus::kOk;
  d.info.status = runStatusName(status);
  d.info.failure_frame = ok ? -1 : failure_frame;
  d.info.failure_reason = ok ? std::string() : failure_reason;
  d.info.failure_kind = ok ? std::string() : failure_kind;
  for (const Attribute& a : results_schema::rootAttributes()) {
    if (a.origin == Origin::kFinish) writeAttribute(d.file, a, d.info);
  }
  d.open = false;
  d.file.commit();
  return s;
}

std::size_t ResultsWriter::frameCount() const { return impl_->frame_t_ns.size(); }
std::size_t ResultsWriter::margCount() const { return impl_->marg_rows; }
const std::string& ResultsWriter::path() const { return impl_->file.path(); }

// ---- reader ---------------------------------------------------------------------------------

namespace {

// Every read a ResultsReader offers beyond the summary, the results discarded: what the trust
// boundary's child runs for Scope::kEverything, so that each later read of the parent's reader
// replays one that ended there.
void readWhole(const ResultsReader& r) {
  r.frameRecords();
  r.margs(true);
  r.sparsifyRecords();
  r.frontendRecords();
  for (const std::int64_t k : r.storedPriors()) r.prior(k);
}

}  // namespace

ResultsReader::ResultsReader(const std::string& path, Scope scope) : path_(path), scope_(scope) {
  h5::checkReadableInChild(path, [&path, scope] {
    const ResultsReader r(path, Unchecked{});
    if (scope == Scope::kEverything) readWhole(r);
    r.summary();
  });
  open();
}

ResultsReader::ResultsReader(const std::string& path, Unchecked) : path_(path) { open(); }

void ResultsReader::requireEverything() const {
  if (scope_ != Scope::kEverything) {
    throw std::logic_error(path_ + ": ResultsReader opened for its summary only");
  }
}

void ResultsReader::open() {
  const std::string& path = path_;
  file_ = h5::File::openReadOnly(path);
  if (!file_.hasAttr("schema_version")) {
    throw InputError(path, 0, "not a marglab results file (no schema_version attribute)");
  }
  info_.schema_version = file_.attr<std::int64_t>("schema_version");
  if (info_.schema_version > kResultsSchemaVersion || info_.schema_version < 1) {
    throw InputError(path, 0,
                     fmt::format("schema_version {} is not supported (this marglab reads 1..{})",
                                 info_.schema_version, kResultsSchemaVersion));
  }
  // Optional attributes absent from older files keep the defaults of RunMetadata (strategy
  // discard, simulated tracks, isa "") and RunInfo.
  for (const Attribute& a : results_schema::rootAttributes()) readAttribute(file_, a, info_);
  for (const std::string& name : file_.attrNames()) {
    if (isSchemaAttribute(name)) continue;
    try {
      info_.metadata.extra.emplace_back(name, file_.attr<std::string>(name));
    } catch (const InputError&) {
      // A non-string attribute added by another tool: not part of RunMetadata::extra.
    }
  }
  // Files written before failure kinds existed: every failure was numerical.
  if (!file_.hasAttr("failure_kind") && info_.status == "failed") info_.failure_kind = "numerical";
}

std::vector<FrameRecord> ResultsReader::frameRecords() const {
  requireEverything();
  return results_schema::readTable(file_.openGroup("frames"), results_schema::frameTable());
}

FrameColumns ResultsReader::frames() const {
  FrameColumns c;
  for (const FrameRecord& r : frameRecords()) {
    c.t_ns.push_back(r.t_ns);
    c.is_keyframe.push_back(r.is_keyframe ? 1 : 0);
    c.n_landmarks.push_back(r.n_landmarks);
    c.n_observations.push_back(r.n_observations);
    c.lm_iterations.push_back(r.lm_iterations);
    c.cost_initial.push_back(r.cost_initial);
    c.cost_final.push_back(r.cost_final);
    c.t_opt_s.push_back(r.t_opt_s);
    c.t_marg_s.push_back(r.t_marg_s);
    c.ate_error.push_back(r.ate_error);
    c.p_est.push_back(r.p_est);
    c.p_gt.push_back(r.p_gt);
    c.q_est.push_back(r.q_est);
  }
  return c;
}

std::size_t ResultsReader::margCount() const {
  requireEverything();
  return static_cast<std::size_t>(file_.openDataset("marg/frame_index").shape().at(0));
}

std::vector<MargRecord> ResultsReader::margs(bool with_eigenvalues) const {
  requireEverything();
  return results_schema::readTable(file_.openGroup("marg"), results_schema::margTable(),
                                   with_eigenvalues ? results_schema::RaggedColumns::kRead
                                                    : results_schema::RaggedColumns::kSkip);
}

VecXd ResultsReader::eigenvalues(std::size_t k) const {
  requireEverything();
  const h5::RaggedReader<double> eig(file_.openGroup("marg"), "eigenvalues");
  if (k >= eig.rows()) {
    throw InputError(
        path_, 0,
        fmt::format("marginalization event {} out of range (the file has {})", k, eig.rows()));
  }
  const std::vector<double> v = eig.row(k);
  return Eigen::Map<const VecXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

MargRecord ResultsReader::marg(std::size_t k) const {
  const std::size_t count = margCount();
  if (k >= count) {
    throw InputError(
        path_, 0, fmt::format("marginalization event {} out of range (the file has {})", k, count));
  }
  return results_schema::readTable(file_.openGroup("marg"), results_schema::margTable(),
                                   results_schema::RaggedColumns::kRead, k, 1)
      .front();
}

// Both groups are absent in files written before them: no rows.
std::vector<SparsifyRecord> ResultsReader::sparsifyRecords() const {
  requireEverything();
  if (!file_.exists("sparsify")) return {};
  return results_schema::readTable(file_.openGroup("sparsify"), results_schema::sparsifyTable());
}

std::vector<FrontendRecord> ResultsReader::frontendRecords() const {
  requireEverything();
  if (!file_.exists("frontend")) return {};
  return results_schema::readTable(file_.openGroup("frontend"), results_schema::frontendTable());
}

std::vector<std::int64_t> ResultsReader::storedPriors() const {
  requireEverything();
  std::vector<std::int64_t> ks;
  if (!file_.exists("marg/priors")) return ks;
  for (const std::string& name : file_.openGroup("marg/priors").members()) {
    try {
      ks.push_back(std::stoll(name));
    } catch (const std::exception&) {
      throw InputError(path_, 0, "/marg/priors/" + name + ": not an event index");
    }
  }
  std::sort(ks.begin(), ks.end());
  return ks;
}

std::optional<StoredPrior> ResultsReader::prior(std::int64_t k) const {
  requireEverything();
  const std::string where = fmt::format("marg/priors/{}", k);
  if (!file_.exists(where)) return std::nullopt;
  const h5::Group g = file_.openGroup(where);
  StoredPrior p;
  p.H_m = g.readMatrix<double>("H_m");
  const auto b = g.readVector<double>("b_m");
  p.b_m = Eigen::Map<const VecXd>(b.data(), static_cast<Eigen::Index>(b.size()));
  if (g.exists("J_m")) {
    p.J_m = g.readMatrix<double>("J_m");
    const auto r = g.readVector<double>("r_m");
    p.r_m = Eigen::Map<const VecXd>(r.data(), static_cast<Eigen::Index>(r.size()));
  }
  const auto kind = g.readVector<std::int32_t>("layout_kind");
  const auto frame_id = g.readVector<std::int64_t>("layout_frame_id");
  const auto offset = g.readVector<std::int32_t>("layout_offset");
  if (frame_id.size() != kind.size() || offset.size() != kind.size()) {
    throw InputError(path_, 0, "/" + where + ": layout columns differ in length");
  }
  for (std::size_t i = 0; i < kind.size(); ++i) {
    if (kind[i] < 0 || kind[i] > 3) {
      throw InputError(path_, 0, "/" + where + fmt::format(": unknown variable kind {}", kind[i]));
    }
    p.layout.push_back({static_cast<PriorVariableKind>(kind[i]), frame_id[i], offset[i]});
  }
  return p;
}

SummaryValues ResultsReader::summary() const {
  return readSummary(file_.openGroup("summary"), path_);
}

}  // namespace marglab
