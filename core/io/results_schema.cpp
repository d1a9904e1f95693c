#include "core/io/results_schema.h"

namespace marglab::results_schema {

namespace {
constexpr Presence kOptional = Presence::kOptional;
constexpr Presence kRequired = Presence::kRequired;
constexpr Origin kFinish = Origin::kFinish;
}  // namespace

// Row order is the order the datasets are created in (and listed in the doc).
const Table<FrameRecord>& frameTable() {
  using R = FrameRecord;
  static const Table<R> table{
      "frames",
      "one row per processed frame",
      {
          {"t_ns", "ns", "frame timestamp", &R::t_ns},
          {"is_keyframe", "1", "1 if the frame became a keyframe", &R::is_keyframe},
          {"n_landmarks", "1", "landmarks in the window", &R::n_landmarks},
          {"n_observations", "1", "visual observations in the window", &R::n_observations},
          {"lm_iterations", "1", "Levenberg-Marquardt iterations of this frame", &R::lm_iterations},
          {"n_connected", "1", "observations of landmarks already in the window", &R::n_connected,
           kOptional},
          {"n_checked", "1", "of those, checked for consistency after LM", &R::n_checked,
           kOptional},
          {"n_inconsistent", "1", "checked observations beyond failure.inconsistent_px",
           &R::n_inconsistent, kOptional},
          {"cost_initial", "1", "window cost 1/2 |r|^2 before LM", &R::cost_initial},
          {"cost_final", "1", "window cost 1/2 |r|^2 after LM", &R::cost_final},
          {"t_opt_s", "s", "optimization wall time", &R::t_opt_s},
          {"t_marg_s", "s", "marginalization wall time", &R::t_marg_s},
          {"right_cx_offset_px", "px",
           "stereo cx offset estimated online after LM, NaN if not estimated",
           &R::right_cx_offset_px, kOptional},
          {"p_est", "m", "estimated position after optimize + marginalize", &R::p_est},
          {"q_est", "1", "estimated orientation, unit quaternion", &R::q_est},
          {"p_gt", "m", "ground-truth position at t_ns (interpolated), NaN if none", &R::p_gt},
          {"ate_error", "m", "position error after the final SE(3) alignment", &R::ate_error,
           kRequired, kFinish},
      }};
  return table;
}

const Table<MargRecord>& margTable() {
  using R = MargRecord;
  static const Table<R> table{
      "marg",
      "one row per marginalization event",
      {
          {"frame_index", "1", "row of /frames that marginalized", &R::frame_index},
          {"t_ns", "ns", "timestamp of that frame", &R::t_ns},
          {"prior_cols", "1", "prior size n", &R::prior_cols},
          {"prior_rows", "1", "rows of J_m (n for squared storage)", &R::prior_rows},
          {"rank", "1", "numerical rank of H_m: #|lambda| > tau", &R::rank},
          {"sigma_min", "1", "smallest eigenvalue of H_m (signed)", &R::sigma_min},
          {"sigma_max", "1", "largest eigenvalue of H_m", &R::sigma_max},
          {"n_negative", "1", "#lambda < -tau", &R::n_negative},
          {"eig_tolerance", "1", "tau = n eps_f64 max|lambda|", &R::eig_tolerance},
          {"dEm", "1", "prior cost change 1/2 e'He + e'b along unit directions", &R::dEm},
          {"eigenvalues", "1", "ascending eigenvalues of H_m per event", &R::eigenvalues},
      }};
  return table;
}

const Table<SparsifyRecord>& sparsifyTable() {
  using R = SparsifyRecord;
  static const Table<R> table{
      "sparsify",
      "one row per keyframe marginalization of a dense / nfr run (Hsiung et al. 2018)",
      {
          {"frame_index", "1", "row of /frames that marginalized the keyframe", &R::frame_index},
          {"t_ns", "ns", "timestamp of that frame", &R::t_ns},
          {"blanket_cols", "1", "columns of the dense prior over the Markov blanket",
           &R::blanket_cols},
          {"n_blanket_poses", "1", "poses in the Markov blanket", &R::n_blanket_poses},
          {"n_blanket_landmarks", "1", "landmarks in the Markov blanket", &R::n_blanket_landmarks},
          {"nnz_dense", "1", "structural non-zeros of the dense prior (both triangles)",
           &R::nnz_dense},
          {"nnz_sparse", "1",
           "structural non-zeros of the sparsified prior (= nnz_dense when kept dense)",
           &R::nnz_sparse},
          {"info_dense", "1", "information e'Le along the unit gauge directions of the dense prior",
           &R::info_dense, kOptional},
          {"info_sparse", "1",
           "information e'Le along the unit gauge directions of the sparsified prior (= dense if "
           "kept)",
           &R::info_sparse, kOptional},
          {"kld", "nats", "KL divergence dense -> sparsified (eq. 10), NaN if dense", &R::kld},
          {"recovered", "1", "1 if the recovered factors replaced the dense prior", &R::recovered},
          {"t_schur_s", "s", "wall time of the marginalization (Schur / flat QR)", &R::t_schur_s},
          {"t_recovery_s", "s", "wall time of the information recovery (eq. 16)", &R::t_recovery_s},
          {"t_insert_s", "s", "wall time of inserting the factors into the window", &R::t_insert_s},
      }};
  return table;
}

const Table<FrontendRecord>& frontendTable() {
  using R = FrontendRecord;
  static const Table<R> table{
      "frontend",
      "one row per frame the track source produced",
      {
          {"t_ns", "ns", "frame timestamp", &R::t_ns},
          {"n_features", "1", "observations of the frame", &R::n_features},
          {"n_tracked", "1", "continued from the previous frame", &R::n_tracked},
          {"n_new", "1", "detected in this frame", &R::n_new},
          {"n_stereo", "1", "with a right match", &R::n_stereo},
          {"t_frontend_s", "s", "front-end wall time without image decoding, NaN if not measured",
           &R::t_frontend_s},
      }};
  return table;
}

const std::vector<Attribute>& rootAttributes() {
  using I = RunInfo;
  using M = RunMetadata;
  static const std::vector<Attribute> attributes{
      {"schema_version", "version of this schema", &I::schema_version},
      {"marglab_version", "marglab version that wrote the file", &I::marglab_version},
      {"git_sha", "git revision of the build that wrote the file", &I::git_sha},
      {"created_utc", "ISO-8601 time of writing, e.g. 2024-05-01T12:34:56Z", &I::created_utc},
      {"dataset", "dataset family, e.g. euroc", &M::dataset},
      {"sequence", "sequence, e.g. MH_01_easy", &M::sequence},
      {"variant", "estimator variant, e.g. ns-qr-sqrt-f32", &M::variant},
      {"precision",
       "floating-point precision of the variant",
       &M::precision,
       {"f32", "f64", "mixed"}},
      {"mode", "stereo (vo) or stereo + IMU (vio)", &M::mode, {"vo", "vio"}},
      {"seed", "simulation seed (bit pattern of the uint64)", &M::seed},
      {"config_toml", "the full effective estimator config (TOML)", &M::config_toml},
      {"qr_threshold_mode",
       "flat-QR threshold mode (empty: no flat QR)",
       &M::qr_threshold_mode,
       {"absolute", "relative", ""}},
      {"qr_threshold", "the flat-QR threshold used (NaN: not applicable)", &M::qr_threshold},
      {"marg_strategy",
       "keyframe marginalization (older files: discard)",
       &M::marg_strategy,
       {"discard", "dense", "nfr"},
       kOptional},
      {"frontend",
       "where the feature tracks came from (older files: simulated)",
       &M::frontend,
       {"images", "simulated", "tracks"},
       kOptional},
      {"isa", "instruction set of the kernels", &M::isa, {"sse2", "avx2", "avx512"}, kOptional},
      {"isa_choice",
       "how the ISA was chosen: --isa NAME, or auto with the measured time per ISA (older files: "
       "empty)",
       &M::isa_choice,
       {},
       kOptional},
      {"tracks_file",
       "frontend tracks: the track file (--tracks, as given); empty otherwise",
       &M::tracks_file,
       {},
       kOptional},
      {"tracks_sequence",
       "frontend tracks: the sequence the track file records (# sequence:); empty otherwise",
       &M::tracks_sequence,
       {},
       kOptional},
      {"tracks_any_sequence",
       "frontend tracks: true when --tracks-any-sequence accepted the file whatever sequence it "
       "records; empty otherwise",
       &M::tracks_any_sequence,
       {"true", "false", ""},
       kOptional},
      {"status", "outcome of the run", &I::status, {"ok", "failed"}, kRequired, kFinish},
      {"failure_frame",
       "row of /frames where the run failed, -1 when ok",
       &I::failure_frame,
       {},
       kRequired,
       kFinish},
      {"failure_reason",
       "why the run failed, empty when ok",
       &I::failure_reason,
       {},
       kRequired,
       kFinish},
      {"failure_kind",
       "numerical, or tracking (the run lost the scene); empty when ok (older files: "
       "numerical for a failed run)",
       &I::failure_kind,
       {"numerical", "tracking", ""},
       kOptional,
       kFinish},
  };
  return attributes;
}

const std::vector<SummaryAttribute>& summaryAttributes() {
  using S = SummaryValues;
  static const std::vector<SummaryAttribute> attributes{
      {"ate_rmse", "m", "RMSE of ate_error (NaN without ground truth)", &S::ate_rmse},
      {"n_ate_pairs", "1", "frames with ground truth and a finite estimate", &S::n_ate_pairs},
      {"n_frames", "1", "rows of /frames", &S::n_frames},
      {"n_marg", "1", "rows of /marg", &S::n_marg},
      {"duration_s", "s", "last - first t_ns of /frames", &S::duration_s},
      {"t_opt_total_s", "s", "sum of /frames/t_opt_s", &S::t_opt_total_s},
      {"t_marg_total_s", "s", "sum of /frames/t_marg_s", &S::t_marg_total_s},
      {"wall_time_s", "s", "wall time of the run (t_opt_total_s + t_marg_total_s if not given)",
       &S::wall_time_s},
      {"realtime_factor", "1", "duration_s / wall_time_s (> 1: faster than real time)",
       &S::realtime_factor},
      {"R_gt_est", "1", "rotation of the alignment p_gt = R p_est + t, row-major", &S::R_gt_est},
      {"t_gt_est", "m", "translation of that alignment", &S::t_gt_est},
  };
  return attributes;
}

std::vector<int> readableVersions() {
  std::vector<int> versions;
  for (int v = 1; v <= kResultsSchemaVersion; ++v) versions.push_back(v);
  return versions;
}

}  // namespace marglab::results_schema
