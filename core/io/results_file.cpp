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
#include "core/linalg/isa.h"
#include "marglab/version.h"

namespace marglab {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

void describe(const h5::Object& o, const char* units, const char* description) {
  o.setAttr("units", units);
  o.setAttr("description", description);
}

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

// ---- writer ---------------------------------------------------------------------------------

struct ResultsWriter::Impl {
  h5::File file;
  bool open = true;
  // /frames
  h5::Appendable<std::int64_t> t_ns;
  h5::Appendable<std::uint8_t> is_keyframe;
  h5::Appendable<std::int32_t> n_landmarks, n_observations, lm_iterations;
  h5::Appendable<double> cost_initial, cost_final, t_opt_s, t_marg_s, p_est, q_est, p_gt, ate_error;
  // /marg
  h5::Appendable<std::int64_t> m_frame_index, m_t_ns;
  h5::Appendable<std::int32_t> m_prior_cols, m_prior_rows, m_rank, m_n_negative;
  h5::Appendable<double> m_sigma_min, m_sigma_max, m_eig_tolerance, m_dEm;
  h5::RaggedWriter<double> m_eigenvalues;
  // /sparsify
  h5::Appendable<std::int64_t> s_frame_index, s_t_ns, s_nnz_dense, s_nnz_sparse;
  h5::Appendable<std::int32_t> s_blanket_cols, s_n_blanket_poses, s_n_blanket_landmarks;
  h5::Appendable<double> s_info_dense, s_info_sparse, s_kld, s_t_schur_s, s_t_recovery_s,
      s_t_insert_s;
  h5::Appendable<std::uint8_t> s_recovered;
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
  const h5::File& f = d->file;
  f.setAttr("schema_version", static_cast<std::int64_t>(kResultsSchemaVersion));
  f.setAttr("marglab_version", MARGLAB_VERSION_STRING);
  f.setAttr("git_sha", MARGLAB_GIT_SHA);
  f.setAttr("created_utc", utcNowIso8601());
  f.setAttr("dataset", metadata.dataset);
  f.setAttr("sequence", metadata.sequence);
  f.setAttr("variant", metadata.variant);
  f.setAttr("precision", metadata.precision);
  f.setAttr("mode", metadata.mode);
  f.setAttr("seed", static_cast<std::int64_t>(metadata.seed));
  f.setAttr("config_toml", metadata.config_toml);
  f.setAttr("qr_threshold_mode", metadata.qr_threshold_mode);
  f.setAttr("qr_threshold", metadata.qr_threshold);
  f.setAttr("marg_strategy", metadata.marg_strategy);
  f.setAttr("frontend", metadata.frontend);
  f.setAttr("isa", metadata.isa.empty() ? std::string(isaName(activeIsa())) : metadata.isa);
  for (const auto& [key, value] : metadata.extra) f.setAttr(key, value);
  // Provisional status: replaced by finish(); only visible if someone inspects the temporary.
  f.setAttr("status", "running");
  f.setAttr("failure_frame", static_cast<std::int64_t>(-1));
  f.setAttr("failure_reason", "");

  const h5::Group frames = f.group("frames");
  d->t_ns = h5::appendable<std::int64_t>(frames, "t_ns");
  describe(d->t_ns.dataset(), "ns", "frame timestamp");
  d->is_keyframe = h5::appendable<std::uint8_t>(frames, "is_keyframe");
  describe(d->is_keyframe.dataset(), "1", "1 if the frame became a keyframe");
  d->n_landmarks = h5::appendable<std::int32_t>(frames, "n_landmarks");
  describe(d->n_landmarks.dataset(), "1", "landmarks in the window");
  d->n_observations = h5::appendable<std::int32_t>(frames, "n_observations");
  describe(d->n_observations.dataset(), "1", "visual observations in the window");
  d->lm_iterations = h5::appendable<std::int32_t>(frames, "lm_iterations");
  describe(d->lm_iterations.dataset(), "1", "Levenberg-Marquardt iterations of this frame");
  d->cost_initial = h5::appendable<double>(frames, "cost_initial");
  describe(d->cost_initial.dataset(), "1", "window cost 1/2 |r|^2 before LM");
  d->cost_final = h5::appendable<double>(frames, "cost_final");
  describe(d->cost_final.dataset(), "1", "window cost 1/2 |r|^2 after LM");
  d->t_opt_s = h5::appendable<double>(frames, "t_opt_s");
  describe(d->t_opt_s.dataset(), "s", "optimization wall time");
  d->t_marg_s = h5::appendable<double>(frames, "t_marg_s");
  describe(d->t_marg_s.dataset(), "s", "marginalization wall time");
  d->p_est = h5::appendableRows<double>(frames, "p_est", 3);
  describe(d->p_est.dataset(), "m", "estimated position after optimize + marginalize");
  d->q_est = h5::appendableRows<double>(frames, "q_est", 4);
  describe(d->q_est.dataset(), "1", "estimated orientation, unit quaternion");
  d->q_est.dataset().setAttr("order", "x y z w");
  d->p_gt = h5::appendableRows<double>(frames, "p_gt", 3);
  describe(d->p_gt.dataset(), "m", "ground-truth position at t_ns (interpolated), NaN if none");
  d->ate_error = h5::appendable<double>(frames, "ate_error");
  describe(d->ate_error.dataset(), "m", "position error after the final SE(3) alignment");

  const h5::Group marg = f.group("marg");
  d->m_frame_index = h5::appendable<std::int64_t>(marg, "frame_index");
  describe(d->m_frame_index.dataset(), "1", "row of /frames that marginalized");
  d->m_t_ns = h5::appendable<std::int64_t>(marg, "t_ns");
  describe(d->m_t_ns.dataset(), "ns", "timestamp of that frame");
  d->m_prior_cols = h5::appendable<std::int32_t>(marg, "prior_cols");
  describe(d->m_prior_cols.dataset(), "1", "prior size n");
  d->m_prior_rows = h5::appendable<std::int32_t>(marg, "prior_rows");
  describe(d->m_prior_rows.dataset(), "1", "rows of J_m (n for squared storage)");
  d->m_rank = h5::appendable<std::int32_t>(marg, "rank");
  describe(d->m_rank.dataset(), "1", "numerical rank of H_m: #|lambda| > tau");
  d->m_sigma_min = h5::appendable<double>(marg, "sigma_min");
  describe(d->m_sigma_min.dataset(), "1", "smallest eigenvalue of H_m (signed)");
  d->m_sigma_max = h5::appendable<double>(marg, "sigma_max");
  describe(d->m_sigma_max.dataset(), "1", "largest eigenvalue of H_m");
  d->m_n_negative = h5::appendable<std::int32_t>(marg, "n_negative");
  describe(d->m_n_negative.dataset(), "1", "#lambda < -tau");
  d->m_eig_tolerance = h5::appendable<double>(marg, "eig_tolerance");
  describe(d->m_eig_tolerance.dataset(), "1", "tau = n eps_f64 max|lambda|");
  d->m_dEm = h5::appendableRows<double>(marg, "dEm", kNumGaugeDirections);
  describe(d->m_dEm.dataset(), "1", "prior cost change 1/2 e'He + e'b along unit directions");
  d->m_dEm.dataset().setAttr("columns", std::vector<std::string>(kGaugeDirectionNames.begin(),
                                                                 kGaugeDirectionNames.end()));
  d->m_eigenvalues = h5::RaggedWriter<double>(marg, "eigenvalues");
  d->m_eigenvalues.group().setAttr("description", "ascending eigenvalues of H_m per event");

  // Created for every run, so that a reader of a discard run sees zero rows, not a missing group.
  const h5::Group sparsify = f.group("sparsify");
  sparsify.setAttr(
      "description",
      "one row per keyframe marginalization of a dense / nfr run (Hsiung et al. 2018)");
  d->s_frame_index = h5::appendable<std::int64_t>(sparsify, "frame_index");
  describe(d->s_frame_index.dataset(), "1", "row of /frames that marginalized the keyframe");
  d->s_t_ns = h5::appendable<std::int64_t>(sparsify, "t_ns");
  describe(d->s_t_ns.dataset(), "ns", "timestamp of that frame");
  d->s_blanket_cols = h5::appendable<std::int32_t>(sparsify, "blanket_cols");
  describe(d->s_blanket_cols.dataset(), "1", "columns of the dense prior over the Markov blanket");
  d->s_n_blanket_poses = h5::appendable<std::int32_t>(sparsify, "n_blanket_poses");
  describe(d->s_n_blanket_poses.dataset(), "1", "poses in the Markov blanket");
  d->s_n_blanket_landmarks = h5::appendable<std::int32_t>(sparsify, "n_blanket_landmarks");
  describe(d->s_n_blanket_landmarks.dataset(), "1", "landmarks in the Markov blanket");
  d->s_nnz_dense = h5::appendable<std::int64_t>(sparsify, "nnz_dense");
  describe(d->s_nnz_dense.dataset(), "1",
           "structural non-zeros of the dense prior (both triangles)");
  d->s_nnz_sparse = h5::appendable<std::int64_t>(sparsify, "nnz_sparse");
  describe(d->s_nnz_sparse.dataset(), "1",
           "structural non-zeros of the sparsified prior (= nnz_dense when kept dense)");
  for (auto [column, name, what] :
       {std::tuple{&d->s_info_dense, "info_dense", "of the dense prior"},
        std::tuple{&d->s_info_sparse, "info_sparse", "of the sparsified prior (= dense if kept)"}}) {
    *column = h5::appendableRows<double>(sparsify, name, kNumGaugeDirections);
    describe(column->dataset(), "1",
             (std::string("information e'Le along the unit gauge directions ") + what).c_str());
    column->dataset().setAttr("columns", std::vector<std::string>(kGaugeDirectionNames.begin(),
                                                                  kGaugeDirectionNames.end()));
  }
  d->s_kld = h5::appendable<double>(sparsify, "kld");
  describe(d->s_kld.dataset(), "nats", "KL divergence dense -> sparsified (eq. 10), NaN if dense");
  d->s_recovered = h5::appendable<std::uint8_t>(sparsify, "recovered");
  describe(d->s_recovered.dataset(), "1", "1 if the recovered factors replaced the dense prior");
  d->s_t_schur_s = h5::appendable<double>(sparsify, "t_schur_s");
  describe(d->s_t_schur_s.dataset(), "s", "wall time of the marginalization (Schur / flat QR)");
  d->s_t_recovery_s = h5::appendable<double>(sparsify, "t_recovery_s");
  describe(d->s_t_recovery_s.dataset(), "s", "wall time of the information recovery (eq. 16)");
  d->s_t_insert_s = h5::appendable<double>(sparsify, "t_insert_s");
  describe(d->s_t_insert_s.dataset(), "s", "wall time of inserting the factors into the window");
  return ResultsWriter(std::move(d));
}

void ResultsWriter::appendFrame(const FrameRecord& r) {
  Impl& d = *impl_;
  d.requireOpen();
  d.t_ns.append(r.t_ns);
  d.is_keyframe.append(static_cast<std::uint8_t>(r.is_keyframe ? 1 : 0));
  d.n_landmarks.append(r.n_landmarks);
  d.n_observations.append(r.n_observations);
  d.lm_iterations.append(r.lm_iterations);
  d.cost_initial.append(r.cost_initial);
  d.cost_final.append(r.cost_final);
  d.t_opt_s.append(r.t_opt_s);
  d.t_marg_s.append(r.t_marg_s);
  d.p_est.append(r.p_est);
  d.q_est.append({r.q_est.x(), r.q_est.y(), r.q_est.z(), r.q_est.w()});
  d.p_gt.append(r.p_gt);
  d.frame_t_ns.push_back(r.t_ns);
  d.frame_p_est.push_back(r.p_est);
  d.frame_p_gt.push_back(r.p_gt);
  d.t_opt_total += r.t_opt_s;
  d.t_marg_total += r.t_marg_s;
}

void ResultsWriter::appendMarg(const MargRecord& m) {
  Impl& d = *impl_;
  d.requireOpen();
  d.m_frame_index.append(m.frame_index);
  d.m_t_ns.append(m.t_ns);
  d.m_prior_cols.append(m.prior_cols);
  d.m_prior_rows.append(m.prior_rows);
  d.m_rank.append(m.rank);
  d.m_sigma_min.append(m.sigma_min);
  d.m_sigma_max.append(m.sigma_max);
  d.m_n_negative.append(m.n_negative);
  d.m_eig_tolerance.append(m.eig_tolerance);
  d.m_dEm.append(m.dEm);
  d.m_eigenvalues.append(m.eigenvalues);
  ++d.marg_rows;
}

void ResultsWriter::appendSparsify(const SparsifyRecord& r) {
  Impl& d = *impl_;
  d.requireOpen();
  d.s_frame_index.append(r.frame_index);
  d.s_t_ns.append(r.t_ns);
  d.s_blanket_cols.append(r.blanket_cols);
  d.s_n_blanket_poses.append(r.n_blanket_poses);
  d.s_n_blanket_landmarks.append(r.n_blanket_landmarks);
  d.s_nnz_dense.append(r.nnz_dense);
  d.s_nnz_sparse.append(r.nnz_sparse);
  d.s_info_dense.append(r.info_dense);
  d.s_info_sparse.append(r.info_sparse);
  d.s_kld.append(r.kld);
  d.s_recovered.append(static_cast<std::uint8_t>(r.recovered ? 1 : 0));
  d.s_t_schur_s.append(r.t_schur_s);
  d.s_t_recovery_s.append(r.t_recovery_s);
  d.s_t_insert_s.append(r.t_insert_s);
}

void ResultsWriter::writeFrontend(const std::vector<FrontendRecord>& rows) {
  Impl& d = *impl_;
  d.requireOpen();
  if (d.frontend_written) throw InputError(d.file.path(), 0, "/frontend written twice");
  d.frontend_written = true;
  const h5::Group g = d.file.group("frontend");
  g.setAttr("description", "one row per frame the track source produced");
  std::vector<std::int64_t> t_ns;
  std::vector<std::int32_t> n_features, n_tracked, n_new, n_stereo;
  std::vector<double> t_frontend;
  for (const FrontendRecord& r : rows) {
    t_ns.push_back(r.t_ns);
    n_features.push_back(r.n_features);
    n_tracked.push_back(r.n_tracked);
    n_new.push_back(r.n_new);
    n_stereo.push_back(r.n_stereo);
    t_frontend.push_back(r.t_frontend_s);
  }
  describe(g.write("t_ns", t_ns), "ns", "frame timestamp");
  describe(g.write("n_features", n_features), "1", "observations of the frame");
  describe(g.write("n_tracked", n_tracked), "1", "continued from the previous frame");
  describe(g.write("n_new", n_new), "1", "detected in this frame");
  describe(g.write("n_stereo", n_stereo), "1", "with a right match");
  describe(g.write("t_frontend_s", t_frontend), "s",
           "front-end wall time without image decoding, NaN if not measured");
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
  d.ate_error.append(ate.error);

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

  const h5::Group g = d.file.group("summary");
  g.setAttr("ate_rmse", s.ate_rmse);
  g.setAttr("n_ate_pairs", s.n_ate_pairs);
  g.setAttr("n_frames", s.n_frames);
  g.setAttr("n_marg", s.n_marg);
  g.setAttr("duration_s", s.duration_s);
  g.setAttr("t_opt_total_s", s.t_opt_total_s);
  g.setAttr("t_marg_total_s", s.t_marg_total_s);
  g.setAttr("wall_time_s", s.wall_time_s);
  g.setAttr("realtime_factor", s.realtime_factor);
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> R = s.R_gt_est;
  g.setAttr("R_gt_est", std::vector<double>(R.data(), R.data() + 9));
  g.setAttr("t_gt_est", std::vector<double>(s.t_gt_est.data(), s.t_gt_est.data() + 3));

  d.file.setAttr("status", runStatusName(status));
  d.file.setAttr("failure_frame", status == RunStatus::kOk ? std::int64_t{-1} : failure_frame);
  d.file.setAttr("failure_reason", status == RunStatus::kOk ? std::string() : failure_reason);
  d.file.setAttr("failure_kind", status == RunStatus::kOk ? std::string() : failure_kind);
  d.open = false;
  d.file.commit();
  return s;
}

std::size_t ResultsWriter::frameCount() const { return impl_->frame_t_ns.size(); }
std::size_t ResultsWriter::margCount() const { return impl_->marg_rows; }
const std::string& ResultsWriter::path() const { return impl_->file.path(); }

// ---- reader ---------------------------------------------------------------------------------

namespace {

std::vector<Eigen::Vector3d> toVec3(const h5::RowMatrix<double>& m) {
  std::vector<Eigen::Vector3d> v(static_cast<std::size_t>(m.rows()));
  for (Eigen::Index i = 0; i < m.rows(); ++i) v[static_cast<std::size_t>(i)] = m.row(i).transpose();
  return v;
}

}  // namespace

ResultsReader::ResultsReader(const std::string& path) : path_(path) {
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
  info_.marglab_version = file_.attr<std::string>("marglab_version");
  info_.git_sha = file_.attr<std::string>("git_sha");
  info_.created_utc = file_.attr<std::string>("created_utc");
  RunMetadata& m = info_.metadata;
  m.dataset = file_.attr<std::string>("dataset");
  m.sequence = file_.attr<std::string>("sequence");
  m.variant = file_.attr<std::string>("variant");
  m.precision = file_.attr<std::string>("precision");
  m.mode = file_.attr<std::string>("mode");
  m.seed = static_cast<std::uint64_t>(file_.attr<std::int64_t>("seed"));
  m.config_toml = file_.attr<std::string>("config_toml");
  m.qr_threshold_mode = file_.attr<std::string>("qr_threshold_mode");
  m.qr_threshold = file_.attr<double>("qr_threshold");
  // Files written before the strategies existed marginalized as discard does.
  m.marg_strategy =
      file_.hasAttr("marg_strategy") ? file_.attr<std::string>("marg_strategy") : "discard";
  // Files written before the image front-end existed all used simulated tracks.
  m.frontend = file_.hasAttr("frontend") ? file_.attr<std::string>("frontend") : "simulated";
  m.isa = file_.hasAttr("isa") ? file_.attr<std::string>("isa") : "";
  static const char* const kKnown[] = {
      "schema_version", "marglab_version",   "git_sha",      "created_utc", "dataset",
      "sequence",       "variant",           "precision",    "mode",        "seed",
      "config_toml",    "qr_threshold_mode", "qr_threshold", "status",      "failure_frame",
      "failure_reason", "marg_strategy",     "frontend",     "isa",         "failure_kind"};
  for (const std::string& name : file_.attrNames()) {
    if (std::find(std::begin(kKnown), std::end(kKnown), name) != std::end(kKnown)) continue;
    try {
      m.extra.emplace_back(name, file_.attr<std::string>(name));
    } catch (const InputError&) {
      // A non-string attribute added by another tool: not part of RunMetadata::extra.
    }
  }
  info_.status = file_.attr<std::string>("status");
  info_.failure_frame = file_.attr<std::int64_t>("failure_frame");
  info_.failure_reason = file_.attr<std::string>("failure_reason");
  info_.failure_kind = file_.hasAttr("failure_kind") ? file_.attr<std::string>("failure_kind")
                       : info_.status == "failed"    ? "numerical"
                                                     : "";
}

FrameColumns ResultsReader::frames() const {
  const h5::Group g = file_.openGroup("frames");
  FrameColumns c;
  c.t_ns = g.readVector<std::int64_t>("t_ns");
  c.is_keyframe = g.readVector<std::uint8_t>("is_keyframe");
  c.n_landmarks = g.readVector<std::int32_t>("n_landmarks");
  c.n_observations = g.readVector<std::int32_t>("n_observations");
  c.lm_iterations = g.readVector<std::int32_t>("lm_iterations");
  c.cost_initial = g.readVector<double>("cost_initial");
  c.cost_final = g.readVector<double>("cost_final");
  c.t_opt_s = g.readVector<double>("t_opt_s");
  c.t_marg_s = g.readVector<double>("t_marg_s");
  c.ate_error = g.readVector<double>("ate_error");
  c.p_est = toVec3(g.readMatrix<double>("p_est"));
  c.p_gt = toVec3(g.readMatrix<double>("p_gt"));
  const h5::RowMatrix<double> q = g.readMatrix<double>("q_est");
  for (Eigen::Index i = 0; i < q.rows(); ++i) {
    c.q_est.emplace_back(q(i, 3), q(i, 0), q(i, 1), q(i, 2));  // stored x y z w
  }
  return c;
}

std::size_t ResultsReader::margCount() const {
  return static_cast<std::size_t>(file_.openDataset("marg/frame_index").shape().at(0));
}

std::vector<MargRecord> ResultsReader::margs(bool with_eigenvalues) const {
  const h5::Group g = file_.openGroup("marg");
  const auto frame_index = g.readVector<std::int64_t>("frame_index");
  const auto t_ns = g.readVector<std::int64_t>("t_ns");
  const auto cols = g.readVector<std::int32_t>("prior_cols");
  const auto rows = g.readVector<std::int32_t>("prior_rows");
  const auto rank = g.readVector<std::int32_t>("rank");
  const auto n_negative = g.readVector<std::int32_t>("n_negative");
  const auto sigma_min = g.readVector<double>("sigma_min");
  const auto sigma_max = g.readVector<double>("sigma_max");
  const auto tolerance = g.readVector<double>("eig_tolerance");
  const auto dEm = g.readMatrix<double>("dEm");
  std::vector<MargRecord> out(frame_index.size());
  std::optional<h5::RaggedReader<double>> eig;
  if (with_eigenvalues) eig.emplace(g, "eigenvalues");
  for (std::size_t k = 0; k < out.size(); ++k) {
    MargRecord& m = out[k];
    m.frame_index = frame_index.at(k);
    m.t_ns = t_ns.at(k);
    m.prior_cols = cols.at(k);
    m.prior_rows = rows.at(k);
    m.rank = rank.at(k);
    m.n_negative = n_negative.at(k);
    m.sigma_min = sigma_min.at(k);
    m.sigma_max = sigma_max.at(k);
    m.eig_tolerance = tolerance.at(k);
    m.dEm = dEm.row(static_cast<Eigen::Index>(k)).transpose();
    if (eig) {
      const std::vector<double> v = eig->row(k);
      m.eigenvalues = Eigen::Map<const VecXd>(v.data(), static_cast<Eigen::Index>(v.size()));
    }
  }
  return out;
}

VecXd ResultsReader::eigenvalues(std::size_t k) const {
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
  const h5::Group g = file_.openGroup("marg");
  const hsize_t row = k;
  auto one = [&](const char* name, auto tag) {
    using T = decltype(tag);
    return g.openDataset(name).readRows<T>(row, 1).at(0);
  };
  MargRecord m;
  m.frame_index = one("frame_index", std::int64_t{});
  m.t_ns = one("t_ns", std::int64_t{});
  m.prior_cols = one("prior_cols", std::int32_t{});
  m.prior_rows = one("prior_rows", std::int32_t{});
  m.rank = one("rank", std::int32_t{});
  m.n_negative = one("n_negative", std::int32_t{});
  m.sigma_min = one("sigma_min", double{});
  m.sigma_max = one("sigma_max", double{});
  m.eig_tolerance = one("eig_tolerance", double{});
  const std::vector<double> dEm = g.openDataset("dEm").readRows<double>(row, 1);
  m.dEm = Eigen::Map<const Vec7d>(dEm.data());
  m.eigenvalues = eigenvalues(k);
  return m;
}

std::vector<SparsifyRecord> ResultsReader::sparsifyRecords() const {
  std::vector<SparsifyRecord> out;
  if (!file_.exists("sparsify")) return out;
  const h5::Group g = file_.openGroup("sparsify");
  const auto frame_index = g.readVector<std::int64_t>("frame_index");
  const auto t_ns = g.readVector<std::int64_t>("t_ns");
  const auto blanket_cols = g.readVector<std::int32_t>("blanket_cols");
  const auto n_poses = g.readVector<std::int32_t>("n_blanket_poses");
  const auto n_landmarks = g.readVector<std::int32_t>("n_blanket_landmarks");
  const auto nnz_dense = g.readVector<std::int64_t>("nnz_dense");
  const auto nnz_sparse = g.readVector<std::int64_t>("nnz_sparse");
  const auto kld = g.readVector<double>("kld");
  const auto recovered = g.readVector<std::uint8_t>("recovered");
  const auto t_schur = g.readVector<double>("t_schur_s");
  const auto t_recovery = g.readVector<double>("t_recovery_s");
  const auto t_insert = g.readVector<double>("t_insert_s");
  const std::size_t n = frame_index.size();
  for (const std::size_t size :
       {t_ns.size(), blanket_cols.size(), n_poses.size(), n_landmarks.size(), nnz_dense.size(),
        nnz_sparse.size(), kld.size(), recovered.size(), t_schur.size(), t_recovery.size(),
        t_insert.size()}) {
    if (size != n) throw InputError(path_, 0, "/sparsify: columns differ in length");
  }
  // Optional (files before them have neither): (n, 7) each.
  std::optional<h5::RowMatrix<double>> info_dense, info_sparse;
  if (g.exists("info_dense") && g.exists("info_sparse")) {
    info_dense = g.readMatrix<double>("info_dense");
    info_sparse = g.readMatrix<double>("info_sparse");
    for (const auto* m : {&*info_dense, &*info_sparse}) {
      if (static_cast<std::size_t>(m->rows()) != n || m->cols() != kNumGaugeDirections) {
        throw InputError(path_, 0, "/sparsify: info_dense / info_sparse are not (rows, 7)");
      }
    }
  }
  out.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    SparsifyRecord& r = out[k];
    if (info_dense) {
      r.info_dense = info_dense->row(static_cast<Eigen::Index>(k)).transpose();
      r.info_sparse = info_sparse->row(static_cast<Eigen::Index>(k)).transpose();
    }
    r.frame_index = frame_index[k];
    r.t_ns = t_ns[k];
    r.blanket_cols = blanket_cols[k];
    r.n_blanket_poses = n_poses[k];
    r.n_blanket_landmarks = n_landmarks[k];
    r.nnz_dense = nnz_dense[k];
    r.nnz_sparse = nnz_sparse[k];
    r.kld = kld[k];
    r.recovered = recovered[k] != 0;
    r.t_schur_s = t_schur[k];
    r.t_recovery_s = t_recovery[k];
    r.t_insert_s = t_insert[k];
  }
  return out;
}

std::vector<FrontendRecord> ResultsReader::frontendRecords() const {
  std::vector<FrontendRecord> out;
  if (!file_.exists("frontend")) return out;
  const h5::Group g = file_.openGroup("frontend");
  const auto t_ns = g.readVector<std::int64_t>("t_ns");
  const auto n_features = g.readVector<std::int32_t>("n_features");
  const auto n_tracked = g.readVector<std::int32_t>("n_tracked");
  const auto n_new = g.readVector<std::int32_t>("n_new");
  const auto n_stereo = g.readVector<std::int32_t>("n_stereo");
  const auto t_frontend = g.readVector<double>("t_frontend_s");
  const std::size_t n = t_ns.size();
  for (const std::size_t size :
       {n_features.size(), n_tracked.size(), n_new.size(), n_stereo.size(), t_frontend.size()}) {
    if (size != n) throw InputError(path_, 0, "/frontend: columns differ in length");
  }
  out.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    out[k] = {t_ns[k], n_features[k], n_tracked[k], n_new[k], n_stereo[k], t_frontend[k]};
  }
  return out;
}

std::vector<std::int64_t> ResultsReader::storedPriors() const {
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
  const h5::Group g = file_.openGroup("summary");
  SummaryValues s;
  s.ate_rmse = g.attr<double>("ate_rmse");
  s.n_ate_pairs = g.attr<std::int64_t>("n_ate_pairs");
  s.n_frames = g.attr<std::int64_t>("n_frames");
  s.n_marg = g.attr<std::int64_t>("n_marg");
  s.duration_s = g.attr<double>("duration_s");
  s.t_opt_total_s = g.attr<double>("t_opt_total_s");
  s.t_marg_total_s = g.attr<double>("t_marg_total_s");
  s.wall_time_s = g.attr<double>("wall_time_s");
  s.realtime_factor = g.attr<double>("realtime_factor");
  const auto R = g.attr<std::vector<double>>("R_gt_est");
  const auto t = g.attr<std::vector<double>>("t_gt_est");
  if (R.size() != 9 || t.size() != 3)
    throw InputError(path_, 0, "/summary: bad alignment attributes");
  s.R_gt_est = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(R.data());
  s.t_gt_est = Eigen::Map<const Eigen::Vector3d>(t.data());
  return s;
}

}  // namespace marglab
