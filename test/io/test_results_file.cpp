// Results file (core/io/results_file.h): a small run written and read back in full, atomicity,
// failed-run round trip, the independent h5py/numpy check (tools/scripts/check_results.py), and the
// `marglab eigdump` CLI on the written file.

#include "common/temp_dir.h"
#include "core/common/source_dir.h"
#include "core/io/results_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/cli_runner.h"
#include "core/common/error.h"
#include "core/geometry/so3.h"
#include "marglab/version.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct SmallRun {
  RunMetadata metadata;
  std::vector<FrameRecord> frames;
  std::vector<MargRecord> margs;
  std::vector<SparsifyRecord> sparsify;
  StoredPrior prior1;  // stored for event 1
  SummaryValues summary;
};

// A rank-deficient square-root prior over `poses` pose blocks (rows = n − 3).
StoredPrior makePrior(int poses, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  const int n = 6 * poses, rows = n - 3;
  StoredPrior p;
  p.J_m = MatXd(rows, n);
  p.r_m = VecXd(rows);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < rows; ++i) p.J_m(i, j) = normal(rng);
  }
  for (int i = 0; i < rows; ++i) p.r_m(i) = 0.1 * normal(rng);
  p.H_m = hessianFromSqrt(p.J_m);
  p.b_m = gradientFromSqrt(p.J_m, p.r_m);
  for (int i = 0; i < poses; ++i) p.layout.push_back({PriorVariableKind::kPose, 100 + i, 6 * i});
  return p;
}

GaugeState stateFor(const PriorLayout& layout) {
  GaugeState s;
  for (const PriorVariable& v : layout) {
    s.T_w_i[v.frame_id] =
        SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.5 * v.offset, 1, 0));
  }
  return s;
}

SmallRun writeSmallRun(const std::string& path, RunStatus status = RunStatus::kOk) {
  SmallRun run;
  RunMetadata& m = run.metadata;
  m.dataset = "euroc";
  m.sequence = "MH_01_easy";
  m.variant = "ns-qr-sqrt-f32";
  m.precision = "f32";
  m.mode = "vio";
  m.seed = 42;
  m.config_toml = "[window]\nmax_kfs = 7\nmax_states = 3\n";
  m.qr_threshold_mode = "absolute";
  m.qr_threshold = 3.4526698e-4;
  m.marg_strategy = "nfr";
  m.extra = {{"host", "test"}};
  ResultsWriter w = ResultsWriter::create(path, m);

  const Eigen::Matrix3d R = expSO3<double>(Eigen::Vector3d(0.1, -0.2, 0.7));
  const Eigen::Vector3d t(1.0, 2.0, -0.5);
  for (int i = 0; i < 8; ++i) {
    FrameRecord f;
    f.t_ns = 1'403'636'579'763'555'584 + i * 50'000'000LL;
    f.is_keyframe = i % 3 == 0;
    f.n_landmarks = 100 + i;
    f.n_observations = 400 + 3 * i;
    f.lm_iterations = 1 + i % 7;
    f.cost_initial = 10.0 + i;
    f.cost_final = 1.0 + 0.5 * i;
    f.t_opt_s = 0.004 + 0.001 * i;
    f.t_marg_s = 0.001;
    const Eigen::Vector3d p_gt(std::cos(0.3 * i), std::sin(0.3 * i), 0.1 * i * i);
    f.p_est =
        R.transpose() * (p_gt - t) + 0.01 * Eigen::Vector3d(std::sin(i), std::cos(2 * i), 0.5);
    f.q_est = Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d(1, 2, 3).normalized()));
    f.p_gt = i == 5 ? Eigen::Vector3d::Constant(kNaN) : p_gt;
    w.appendFrame(f);
    run.frames.push_back(f);
  }
  const int poses[3] = {2, 2, 3};
  for (int k = 0; k < 3; ++k) {
    const StoredPrior p = makePrior(poses[k], 10 + k);
    const PriorDiagnostics d = diagnoseSqrtPrior(p.J_m, p.r_m, p.layout, stateFor(p.layout), 7 + k);
    const MargRecord mr =
        makeMargRecord(2 * k + 1, run.frames[2 * k + 1].t_ns, static_cast<int>(p.J_m.rows()), d);
    w.appendMarg(mr);
    run.margs.push_back(mr);
    if (k == 1) {
      w.appendPriorMatrices(1, p.layout, p.H_m, p.b_m, &p.J_m, &p.r_m);
      run.prior1 = p;
    }
  }
  // Keyframe marginalizations at frames 3 and 6: recovered, and kept dense (an nfr fallback).
  for (const int frame : {3, 6}) {
    SparsifyRecord s;
    s.frame_index = frame;
    s.t_ns = run.frames[frame].t_ns;
    s.blanket_cols = 15 + 3 * frame;
    s.n_blanket_poses = 1;
    s.n_blanket_landmarks = frame;
    s.nnz_dense = s.blanket_cols * s.blanket_cols;
    s.recovered = frame == 3;
    s.nnz_sparse = s.recovered ? 225 + 2 * 27 * frame + 9 * frame : s.nnz_dense;
    s.kld = s.recovered ? 0.125 * frame : kNaN;
    for (int k = 0; k < kNumGaugeDirections; ++k) s.info_dense(k) = 1e3 * frame + k;
    s.info_sparse = s.recovered ? Vec7d(2.5 * s.info_dense) : s.info_dense;
    s.t_schur_s = 1e-3 * frame;
    s.t_recovery_s = 2e-3 * frame;
    s.t_insert_s = s.recovered ? 1e-4 * frame : 0.0;
    w.appendSparsify(s);
    run.sparsify.push_back(s);
  }
  EXPECT_EQ(w.frameCount(), 8u);
  EXPECT_EQ(w.margCount(), 3u);
  RunSummary summary;
  summary.wall_time_s = 0.25;
  run.summary = status == RunStatus::kOk
                    ? w.finish(summary)
                    : w.finish(summary, status, 6, "position error 7.2 m > 5 m");
  return run;
}

class ResultsFileTest : public test::TempDirTest {
 protected:
  std::string file(const std::string& name) const { return (dir_ / name).string(); }
  std::size_t entries() const {
    return static_cast<std::size_t>(
        std::distance(fs::directory_iterator(dir_), fs::directory_iterator()));
  }
};

template <typename A, typename B>
void expectNanEqual(const A& a, const B& b) {
  ASSERT_EQ(a.size(), b.size());
  for (Eigen::Index i = 0; i < a.size(); ++i) {
    if (std::isnan(b(i))) {
      EXPECT_TRUE(std::isnan(a(i)));
    } else {
      EXPECT_EQ(a(i), b(i));
    }
  }
}

// The root attributes, the metadata and /frames of a small run, as written.
void expectInfoAndFrames(const ResultsReader& r, const SmallRun& run) {
  const RunInfo& info = r.info();
  EXPECT_EQ(info.schema_version, kResultsSchemaVersion);
  EXPECT_EQ(info.marglab_version, MARGLAB_VERSION_STRING);
  EXPECT_EQ(info.git_sha, MARGLAB_GIT_SHA);
  EXPECT_EQ(info.created_utc.size(), 20u);
  EXPECT_EQ(info.created_utc.back(), 'Z');
  EXPECT_EQ(info.status, "ok");
  EXPECT_EQ(info.failure_frame, -1);
  EXPECT_EQ(info.failure_reason, "");
  const RunMetadata& m = info.metadata;
  EXPECT_EQ(m.dataset, run.metadata.dataset);
  EXPECT_EQ(m.sequence, run.metadata.sequence);
  EXPECT_EQ(m.variant, run.metadata.variant);
  EXPECT_EQ(m.precision, run.metadata.precision);
  EXPECT_EQ(m.mode, run.metadata.mode);
  EXPECT_EQ(m.seed, run.metadata.seed);
  EXPECT_EQ(m.config_toml, run.metadata.config_toml);
  EXPECT_EQ(m.qr_threshold_mode, run.metadata.qr_threshold_mode);
  EXPECT_EQ(m.qr_threshold, run.metadata.qr_threshold);
  EXPECT_EQ(m.marg_strategy, "nfr");
  EXPECT_EQ(m.extra, run.metadata.extra);  // marg_strategy is not an extra attribute

  const FrameColumns f = r.frames();
  ASSERT_EQ(f.size(), run.frames.size());
  for (std::size_t i = 0; i < f.size(); ++i) {
    const FrameRecord& e = run.frames[i];
    EXPECT_EQ(f.t_ns[i], e.t_ns);
    EXPECT_EQ(f.is_keyframe[i], e.is_keyframe ? 1 : 0);
    EXPECT_EQ(f.n_landmarks[i], e.n_landmarks);
    EXPECT_EQ(f.n_observations[i], e.n_observations);
    EXPECT_EQ(f.lm_iterations[i], e.lm_iterations);
    EXPECT_EQ(f.cost_initial[i], e.cost_initial);
    EXPECT_EQ(f.cost_final[i], e.cost_final);
    EXPECT_EQ(f.t_opt_s[i], e.t_opt_s);
    EXPECT_EQ(f.t_marg_s[i], e.t_marg_s);
    EXPECT_EQ(f.p_est[i], e.p_est);
    EXPECT_EQ(f.q_est[i].coeffs(), e.q_est.coeffs());
    expectNanEqual(f.p_gt[i], e.p_gt);
  }
  EXPECT_EQ(r.file().openDataset("frames/q_est").attr<std::string>("order"), "x y z w");
}

// /marg (with its eigenvalues) and /sparsify of a small run, as written.
void expectMargAndSparsify(const ResultsReader& r, const SmallRun& run) {
  ASSERT_EQ(r.margCount(), 3u);
  const std::vector<MargRecord> margs = r.margs();
  for (std::size_t k = 0; k < 3; ++k) {
    for (const MargRecord& g : {margs[k], r.marg(k)}) {
      const MargRecord& e = run.margs[k];
      EXPECT_EQ(g.frame_index, e.frame_index);
      EXPECT_EQ(g.t_ns, e.t_ns);
      EXPECT_EQ(g.prior_cols, e.prior_cols);
      EXPECT_EQ(g.prior_rows, e.prior_rows);
      EXPECT_EQ(g.rank, e.rank);
      EXPECT_EQ(g.n_negative, e.n_negative);
      EXPECT_EQ(g.sigma_min, e.sigma_min);
      EXPECT_EQ(g.sigma_max, e.sigma_max);
      EXPECT_EQ(g.eig_tolerance, e.eig_tolerance);
      EXPECT_EQ(g.dEm, e.dEm);
      EXPECT_EQ(g.eigenvalues, e.eigenvalues);
    }
    EXPECT_EQ(r.eigenvalues(k), run.margs[k].eigenvalues);
  }
  EXPECT_EQ(margs[2].prior_cols, 18);
  EXPECT_EQ(margs[2].rank, 15);
  EXPECT_EQ(r.file().openDataset("marg/dEm").attr<std::vector<std::string>>("columns"),
            (std::vector<std::string>{"x", "y", "z", "roll", "pitch", "yaw", "random"}));
  EXPECT_THROW(r.marg(3), InputError);
  EXPECT_THROW(r.eigenvalues(3), InputError);

  const std::vector<SparsifyRecord> sparsify = r.sparsifyRecords();
  ASSERT_EQ(sparsify.size(), run.sparsify.size());
  for (std::size_t k = 0; k < sparsify.size(); ++k) {
    const SparsifyRecord &g = sparsify[k], &e = run.sparsify[k];
    EXPECT_EQ(g.frame_index, e.frame_index);
    EXPECT_EQ(g.t_ns, e.t_ns);
    EXPECT_EQ(g.blanket_cols, e.blanket_cols);
    EXPECT_EQ(g.n_blanket_poses, e.n_blanket_poses);
    EXPECT_EQ(g.n_blanket_landmarks, e.n_blanket_landmarks);
    EXPECT_EQ(g.nnz_dense, e.nnz_dense);
    EXPECT_EQ(g.nnz_sparse, e.nnz_sparse);
    EXPECT_EQ(std::isnan(g.kld), std::isnan(e.kld));
    if (!std::isnan(e.kld)) {
      EXPECT_EQ(g.kld, e.kld);
    }
    EXPECT_EQ(g.info_dense, e.info_dense);
    EXPECT_EQ(g.info_sparse, e.info_sparse);
    EXPECT_EQ(g.recovered, e.recovered);
    EXPECT_EQ(g.t_schur_s, e.t_schur_s);
    EXPECT_EQ(g.t_recovery_s, e.t_recovery_s);
    EXPECT_EQ(g.t_insert_s, e.t_insert_s);
  }
  EXPECT_EQ(r.file().openDataset("sparsify/kld").attr<std::string>("units"), "nats");
  EXPECT_EQ(r.file().openDataset("sparsify/info_sparse").attr<std::vector<std::string>>("columns"),
            std::vector<std::string>(kGaugeDirectionNames.begin(), kGaugeDirectionNames.end()));

  EXPECT_EQ(r.storedPriors(), std::vector<std::int64_t>{1});
  EXPECT_FALSE(r.prior(0));
  const std::optional<StoredPrior> p = r.prior(1);
  ASSERT_TRUE(p);
  EXPECT_EQ(p->H_m, run.prior1.H_m);
  EXPECT_EQ(p->b_m, run.prior1.b_m);
  EXPECT_EQ(p->J_m, run.prior1.J_m);
  EXPECT_EQ(p->r_m, run.prior1.r_m);
  ASSERT_EQ(p->layout.size(), run.prior1.layout.size());
  for (std::size_t i = 0; i < p->layout.size(); ++i) {
    EXPECT_EQ(p->layout[i].kind, run.prior1.layout[i].kind);
    EXPECT_EQ(p->layout[i].frame_id, run.prior1.layout[i].frame_id);
    EXPECT_EQ(p->layout[i].offset, run.prior1.layout[i].offset);
  }
}

TEST_F(ResultsFileTest, EveryDatasetAndAttributeRoundTrips) {
  const std::string path = file("run.h5");
  const SmallRun run = writeSmallRun(path);
  EXPECT_EQ(entries(), 1u);  // the committed file only, no temporary
  const ResultsReader r(path);

  expectInfoAndFrames(r, run);
  const FrameColumns f = r.frames();

  // ATE: independent alignment with Eigen::umeyama over the frames that have GT.
  std::vector<int> rows;
  for (int i = 0; i < 8; ++i) {
    if (i != 5) rows.push_back(i);
  }
  Eigen::Matrix3Xd S(3, rows.size()), D(3, rows.size());
  for (std::size_t j = 0; j < rows.size(); ++j) {
    S.col(j) = run.frames[rows[j]].p_est;
    D.col(j) = run.frames[rows[j]].p_gt;
  }
  const Eigen::Matrix4d T = Eigen::umeyama(S, D, false);
  double sum = 0.0;
  for (std::size_t j = 0; j < rows.size(); ++j) {
    const double e =
        (D.col(j) - T.topLeftCorner<3, 3>() * S.col(j) - T.topRightCorner<3, 1>()).norm();
    EXPECT_NEAR(f.ate_error[rows[j]], e, 1e-12);
    sum += e * e;
  }
  EXPECT_TRUE(std::isnan(f.ate_error[5]));
  const SummaryValues s = r.summary();
  EXPECT_NEAR(s.ate_rmse, std::sqrt(sum / rows.size()), 1e-12);
  EXPECT_GT(s.ate_rmse, 1e-3);  // the added noise is not aligned away
  EXPECT_EQ(s.ate_rmse, run.summary.ate_rmse);
  EXPECT_EQ(s.n_ate_pairs, 7);
  EXPECT_EQ(s.n_frames, 8);
  EXPECT_EQ(s.n_marg, 3);
  EXPECT_DOUBLE_EQ(s.duration_s, 0.35);
  double t_opt = 0.0;
  for (const auto& fr : run.frames) t_opt += fr.t_opt_s;
  EXPECT_DOUBLE_EQ(s.t_opt_total_s, t_opt);
  EXPECT_DOUBLE_EQ(s.t_marg_total_s, 0.008);
  EXPECT_EQ(s.wall_time_s, 0.25);
  EXPECT_DOUBLE_EQ(s.realtime_factor, 0.35 / 0.25);
  EXPECT_LT((s.R_gt_est - T.topLeftCorner<3, 3>()).norm(), 1e-12);
  EXPECT_LT((s.t_gt_est - T.topRightCorner<3, 1>()).norm(), 1e-12);

  expectMargAndSparsify(r, run);
}

TEST_F(ResultsFileTest, SquaredStoragePriorAndVioLayoutRoundTrip) {
  const std::string path = file("sq.h5");
  ResultsWriter w = ResultsWriter::create(path, RunMetadata{});
  const PriorLayout layout = {{PriorVariableKind::kPose, 5, 0},
                              {PriorVariableKind::kVelocity, 5, 6},
                              {PriorVariableKind::kGyroBias, 5, 9},
                              {PriorVariableKind::kAccelBias, 5, 12}};
  const MatXd H = MatXd::Identity(15, 15) * 2.0;
  const VecXd b = VecXd::LinSpaced(15, -1.0, 1.0);
  w.appendPriorMatrices(0, layout, H, b);
  EXPECT_THROW(w.appendPriorMatrices(0, layout, H, b), std::invalid_argument);  // twice
  EXPECT_THROW(w.appendPriorMatrices(1, layout, MatXd::Identity(12, 12), VecXd::Zero(12)),
               std::invalid_argument);  // layout larger than the matrix
  const SummaryValues s = w.finish(RunSummary{});
  EXPECT_TRUE(std::isnan(s.ate_rmse));  // no frames, no GT
  EXPECT_THROW(w.appendFrame(FrameRecord{}), InputError);

  const ResultsReader r(path);
  EXPECT_EQ(r.frames().size(), 0u);
  EXPECT_EQ(r.margCount(), 0u);
  const auto p = r.prior(0);
  ASSERT_TRUE(p);
  EXPECT_EQ(p->H_m, H);
  EXPECT_EQ(p->b_m, b);
  EXPECT_EQ(p->J_m.size(), 0);
  ASSERT_EQ(p->layout.size(), 4u);
  EXPECT_EQ(p->layout[3].kind, PriorVariableKind::kAccelBias);
  EXPECT_EQ(p->layout[3].offset, 12);
  EXPECT_EQ(r.file().openGroup("marg/priors/0").attr<std::string>("storage"), "sq");
}

TEST_F(ResultsFileTest, SparsifyGroupHasZeroRowsForDiscardAndIsOptionalForOlderFiles) {
  const std::string path = file("discard.h5");
  ResultsWriter::create(path, RunMetadata{}).finish(RunSummary{});
  {
    const ResultsReader r(path);
    EXPECT_EQ(r.info().metadata.marg_strategy, "discard");
    EXPECT_EQ(r.file().attr<std::string>("marg_strategy"), "discard");
    ASSERT_TRUE(r.file().exists("sparsify/kld"));
    EXPECT_EQ(r.file().openDataset("sparsify/kld").shape(), std::vector<hsize_t>{0});
    EXPECT_TRUE(r.sparsifyRecords().empty());
  }
  // A file written before the strategies existed: neither the group nor the attribute.
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  EXPECT_GE(H5Ldelete(f, "sparsify", H5P_DEFAULT), 0);
  EXPECT_GE(H5Adelete(f, "marg_strategy"), 0);
  H5Fclose(f);
  const ResultsReader r(path);
  EXPECT_FALSE(r.file().exists("sparsify"));
  EXPECT_FALSE(r.file().hasAttr("marg_strategy"));
  EXPECT_EQ(r.info().metadata.marg_strategy, "discard");
  EXPECT_TRUE(r.sparsifyRecords().empty());
}

TEST_F(ResultsFileTest, FrontendGroupRoundTripsAndIsOptionalForOlderFiles) {
  const std::string path = file("frontend.h5");
  RunMetadata metadata;
  metadata.frontend = "images";
  {
    ResultsWriter w = ResultsWriter::create(path, metadata);
    w.writeFrontend({{10, 120, 0, 120, 100, 0.004}, {20, 125, 118, 7, 101, 0.003}});
    w.finish(RunSummary{});
  }
  {
    const ResultsReader r(path);
    EXPECT_EQ(r.info().metadata.frontend, "images");
    const std::vector<FrontendRecord> rows = r.frontendRecords();
    ASSERT_EQ(rows.size(), 2u);
    EXPECT_EQ(rows[1].t_ns, 20);
    EXPECT_EQ(rows[1].n_features, 125);
    EXPECT_EQ(rows[1].n_tracked, 118);
    EXPECT_EQ(rows[1].n_new, 7);
    EXPECT_EQ(rows[1].n_stereo, 101);
    EXPECT_EQ(rows[1].t_frontend_s, 0.003);
  }
  // A file written before the front-end existed: neither the group nor the attribute.
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  EXPECT_GE(H5Ldelete(f, "frontend", H5P_DEFAULT), 0);
  EXPECT_GE(H5Adelete(f, "frontend"), 0);
  H5Fclose(f);
  const ResultsReader r(path);
  EXPECT_EQ(r.info().metadata.frontend, "simulated");
  EXPECT_TRUE(r.frontendRecords().empty());
}

TEST_F(ResultsFileTest, WriterDestroyedWithoutFinishLeavesNoFile) {
  const std::string path = file("unfinished.h5");
  {
    ResultsWriter w = ResultsWriter::create(path, RunMetadata{});
    w.appendFrame(FrameRecord{});
    EXPECT_EQ(entries(), 1u);  // the temporary
    EXPECT_FALSE(fs::exists(path));
  }
  EXPECT_FALSE(fs::exists(path));
  EXPECT_EQ(entries(), 0u);
}

TEST_F(ResultsFileTest, FailedRunIsACompleteFileWithItsReason) {
  const std::string path = file("failed.h5");
  writeSmallRun(path, RunStatus::kFailed);
  const ResultsReader r(path);
  EXPECT_EQ(r.info().status, "failed");
  EXPECT_EQ(r.info().failure_frame, 6);
  EXPECT_EQ(r.info().failure_reason, "position error 7.2 m > 5 m");
  EXPECT_EQ(r.frames().size(), 8u);
  EXPECT_EQ(r.summary().n_frames, 8);
}

// Scope::kSummary: the child of the trust boundary read the root attributes and /summary only,
// so nothing else may be read here.
TEST_F(ResultsFileTest, SummaryScopeReadsTheSummaryAndNothingElse) {
  const std::string path = file("run.h5");
  writeSmallRun(path);
  const ResultsReader whole(path);
  const ResultsReader r(path, ResultsReader::Scope::kSummary);
  EXPECT_EQ(r.info().metadata.variant, whole.info().metadata.variant);
  EXPECT_EQ(r.summary().n_frames, whole.summary().n_frames);
  EXPECT_THROW(r.frames(), std::logic_error);
  EXPECT_THROW(r.margs(), std::logic_error);
  EXPECT_THROW(r.storedPriors(), std::logic_error);
}

TEST_F(ResultsFileTest, ReaderRejectsMissingAndForeignFiles) {
  EXPECT_THROW(ResultsReader{file("missing.h5")}, InputError);
  const std::string foreign = file("foreign.h5");
  {
    h5::File f = h5::File::create(foreign);
    f.write("x", std::vector<double>{1.0});
    f.commit();
  }
  try {
    ResultsReader r(foreign);
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not a marglab results file"), std::string::npos);
  }
  const std::string newer = file("newer.h5");
  {
    h5::File f = h5::File::create(newer);
    f.setAttr("schema_version", 99);
    f.commit();
  }
  EXPECT_THROW(ResultsReader{newer}, InputError);
}

TEST_F(ResultsFileTest, PythonCheckerAgreesAndDetectsTampering) {
  const std::string python = test::findPythonWithH5py();
  if (python.empty())
    GTEST_SKIP() << "no python3 with h5py and numpy (tried /usr/bin/python3, python3)";
  const std::string path = file("run.h5");
  writeSmallRun(path);
  const std::string script = std::string(sourceDir()) + "/tools/scripts/check_results.py";
  EXPECT_EQ(std::system((python + " '" + script + "' '" + path + "' > /dev/null").c_str()), 0);

  const std::string failed = file("failed.h5");
  writeSmallRun(failed, RunStatus::kFailed);
  EXPECT_EQ(std::system((python + " '" + script + "' '" + failed + "' > /dev/null").c_str()), 0);

  // Each edit alone makes the file inconsistent.
  for (const std::string& change :
       {std::string("f['summary'].attrs['ate_rmse'] *= 1.001"),
        std::string("f['sparsify/nnz_sparse'][0] = f['sparsify/nnz_dense'][0] + 1"),
        std::string("f['sparsify/kld'][0] = -0.5"), std::string("f['sparsify/frame_index'][1] = 8"),
        std::string("f.attrs['marg_strategy'] = 'discard'")}) {
    SCOPED_TRACE(change);
    const std::string tampered = file("tampered.h5");
    fs::copy_file(path, tampered, fs::copy_options::overwrite_existing);
    const std::string edit = python + " -c \"import h5py; f = h5py.File('" + tampered +
                             "', 'r+'); " + change + "; f.close()\"";
    ASSERT_EQ(std::system(edit.c_str()), 0);
    EXPECT_NE(
        std::system(
            (python + " '" + script + "' '" + tampered + "' 2> /dev/null > /dev/null").c_str()),
        0);
  }
}

// ---- marglab eigdump ------------------------------------------------------------------------

int countLines(const std::string& text, const std::string& prefix) {
  std::istringstream in(text);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) n += line.rfind(prefix, 0) == 0 ? 1 : 0;
  return n;
}

TEST_F(ResultsFileTest, EigdumpPrintsEventsCsvAndMatrices) {
  const std::string path = file("run.h5");
  const SmallRun run = writeSmallRun(path);
  const std::string q = "'" + path + "' ";

  const test::CliResult last = test::runCli("eigdump " + q);
  ASSERT_EQ(last.exit_code, 0) << last.output;
  EXPECT_NE(last.output.find("marg 2 of 3: frame 5"), std::string::npos) << last.output;
  EXPECT_NE(last.output.find("prior 18 cols, 15 rows, rank 15"), std::string::npos) << last.output;
  EXPECT_NE(last.output.find("ns-qr-sqrt-f32"), std::string::npos);

  EXPECT_NE(test::runCli("eigdump --marg 0 " + q).output.find("marg 0 of 3"), std::string::npos);
  EXPECT_NE(test::runCli("eigdump --marg -3 " + q).output.find("marg 0 of 3"), std::string::npos);

  const test::CliResult csv = test::runCli("eigdump --csv --marg 1 " + q);
  ASSERT_EQ(csv.exit_code, 0) << csv.output;
  std::istringstream in(csv.output);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "marg_index,eig_index,value");
  int i = 0;
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::string k, idx, value;
    std::getline(row, k, ',');
    std::getline(row, idx, ',');
    std::getline(row, value);
    EXPECT_EQ(k, "1");
    EXPECT_EQ(std::stoi(idx), i);
    EXPECT_EQ(std::stod(value), run.margs[1].eigenvalues(i));  // %.17g round-trips exactly
    ++i;
  }
  EXPECT_EQ(i, run.margs[1].prior_cols);

  const test::CliResult all = test::runCli("eigdump --all --csv " + q);
  ASSERT_EQ(all.exit_code, 0);
  EXPECT_EQ(
      countLines(all.output, "0,") + countLines(all.output, "1,") + countLines(all.output, "2,"),
      12 + 12 + 18);

  const test::CliResult matrix = test::runCli("eigdump --matrix --marg 1 " + q);
  ASSERT_EQ(matrix.exit_code, 0) << matrix.output;
  for (const char* needle : {"sqrt storage", "pose", "frame 101", "H_m (12x12)", "b_m (12x1)",
                             "J_m (9x12)", "r_m (9x1)"}) {
    EXPECT_NE(matrix.output.find(needle), std::string::npos) << needle << "\n" << matrix.output;
  }
  const test::CliResult all_matrix = test::runCli("eigdump --all --matrix " + q);
  EXPECT_EQ(all_matrix.exit_code, 0);
  EXPECT_EQ(countLines(all_matrix.output, "  marg 0: prior matrices not stored"), 1);

  const test::CliResult not_stored = test::runCli("eigdump --matrix --marg 0 " + q);
  EXPECT_EQ(not_stored.exit_code, 1);
  EXPECT_NE(not_stored.output.find("not stored (stored events: 1"), std::string::npos)
      << not_stored.output;
}

TEST_F(ResultsFileTest, EigdumpErrorsHaveClearMessagesAndExitCodes) {
  const std::string path = file("run.h5");
  writeSmallRun(path);
  const std::string q = "'" + path + "' ";
  const test::CliResult out_of_range = test::runCli("eigdump --marg 3 " + q);
  EXPECT_EQ(out_of_range.exit_code, 1);
  EXPECT_NE(out_of_range.output.find("out of range, the run has 3"), std::string::npos)
      << out_of_range.output;
  EXPECT_EQ(test::runCli("eigdump --marg -4 " + q).exit_code, 1);
  EXPECT_EQ(test::runCli("eigdump --marg abc " + q).exit_code, 2);
  EXPECT_EQ(test::runCli("eigdump --marg 1 --all " + q).exit_code, 2);
  EXPECT_EQ(test::runCli("eigdump").exit_code, 2);
  const test::CliResult missing = test::runCli("eigdump '" + file("missing.h5") + "'");
  EXPECT_EQ(missing.exit_code, 1);  // a missing file is an input error in every verb
  EXPECT_NE(missing.output.find("missing.h5: no such file"), std::string::npos) << missing.output;
  const test::CliResult help = test::runCli("eigdump --help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.output.find("Default: the"), std::string::npos) << help.output;
}

}  // namespace
}  // namespace marglab
