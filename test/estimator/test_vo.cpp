// The VO estimator through its public interface on noise-free simulated stereo tracks along an
// analytic street-like trajectory: every variant recovers the truth, ns/sc steps and qr/sc priors
// agree on the same window, and the gauge-free prior has the 6-dof gauge nullspace.

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <cmath>
#include <type_traits>

#include "core/diagnostics/diagnostics.h"
#include "core/estimator/estimator.h"
#include "core/estimator/marg_policy.h"
#include "core/estimator/marg_rounding.h"
#include "core/estimator/window_snapshot.h"
#include "core/pipeline/run.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/world.h"
#include "estimator/variant_params.h"
#include "estimator/vo_scenario.h"

namespace marglab {
namespace {

using test::CircleTrajectory;
using test::kittiLikeCalib;

struct Scenario {
  CircleTrajectory trajectory;
  StereoCalib calib = kittiLikeCalib();
  TrackStream stream;
  explicit Scenario(int frames, bool noise = false) {
    WorldOptions world_options = defaultWorldOptions(DatasetKind::kKitti);
    const World world = makeWorld(trajectory, world_options, 3);
    TrackerOptions tracker;
    tracker.grid_cell_px = 30;
    tracker.max_depth = 250;
    tracker.noise = noise;
    tracker.outliers = false;
    std::vector<int64_t> t_ns;
    for (int i = 0; i < frames; ++i) t_ns.push_back(int64_t{100'000'000} * i);
    stream = simulateTracks(trajectory, calib, t_ns, world, tracker, 5);
  }
  SE3<double> truth(int64_t t_ns) const {
    const TrajectorySample s = trajectory.evaluate(t_ns);
    return SE3<double>(s.R_w_b, s.p_w_b);
  }
};

EstimatorSettings testConfig() {
  EstimatorSettings config;
  config.min_frames_after_kf = 1;
  return config;
}

class VoVariantTest : public ::testing::TestWithParam<std::string> {};

template <typename Scalar>
double maxPositionError(const Scenario& scenario, const Variant& variant) {
  SlidingWindowEstimator<Scalar> estimator(testConfig(), variant, rigFromCalib(scenario.calib),
                                           scenario.truth(scenario.stream.frames.front().t_ns));
  double max_error = 0;
  for (const TrackFrame& frame : scenario.stream.frames) {
    const FrameResult result = estimator.processFrame(frame);
    EXPECT_TRUE(result.status.ok()) << result.status.toString();
    if (!result.status.ok()) return std::numeric_limits<double>::infinity();
    max_error =
        std::max(max_error, (result.p_est - scenario.truth(frame.t_ns).translation()).norm());
  }
  return max_error;
}

TEST_P(VoVariantTest, NoiseFreeTracksRecoverTheTruthToAMillimetre) {
  static const Scenario scenario(200);
  const Variant variant = Variant::parse(GetParam());
  ASSERT_EQ(variant.precision, Precision::kF64);
  EXPECT_LT(maxPositionError<double>(scenario, variant), 1e-3);
}

INSTANTIATE_TEST_SUITE_P(F64, VoVariantTest, test::doublePrecisionVariants(),
                         test::variantTestName);

// Mixed precision (landmarks eliminated in f32, the rest in f64) on the same tracks.
TEST(VoMixed, NoiseFreeTracksRecoverTheTruthToAMillimetre) {
  static const Scenario scenario(200);
  EXPECT_LT(maxPositionError<double>(scenario, Variant::parse("ns-qr-sqrt-mixed")), 1e-3);
}

// The same window's damped LM step with float landmark blocks in a double reduced system solves
// the double system with a backward error of float size: the float elimination perturbs the
// reduced system by O(ε_f ‖H‖), so ‖(H + D) δ + b‖ ≤ c ε_f (‖H + D‖ ‖δ‖ + ‖b‖) with c a small
// multiple of the rows per landmark, whatever κ(H) (1e6 here, from the gauge prior). The all-double
// step's backward error is of double size, far below: the elimination did run in float.
// One damped LM step of the window with the variant's linearization; the undamped reduced system
// (λ-independent part) in *H, *b when given.
VecXd dampedStep(const Window<double>& window, const char* variant, double lambda, MatXd* H,
                 VecXd* b) {
  Linearization<double>::Options options;
  options.lambda_min = testConfig().lambda_min;
  const auto lin = makeLinearization<double>(Variant::parse(variant), options);
  lin->linearize(window);
  EXPECT_TRUE(lin->eliminate().ok());
  if (H != nullptr) *H = lin->reducedHessian();
  if (b != nullptr) *b = lin->reducedGradient();
  LinearStep<double> step;
  EXPECT_TRUE(lin->solve(lambda, &step).ok());
  return step.delta;
}

TEST(VoMixed, StepSolvesTheDoubleSystemToFloatBackwardError) {
  const Scenario scenario(40, true);
  SlidingWindowEstimator<double> estimator(testConfig(), Variant::parse("ns-qr-sqrt-f64"),
                                           rigFromCalib(scenario.calib), scenario.truth(0));
  for (int i = 0; i < 30; ++i) {
    ASSERT_TRUE(estimator.processFrame(scenario.stream.frames[i]).status.ok());
  }
  const double lambda = 1e-4;
  MatXd H;
  VecXd b;
  const VecXd ref = dampedStep(estimator.window(), "ns-qr-sqrt-f64", lambda, &H, &b);
  const VecXd mixed = dampedStep(estimator.window(), "ns-qr-sqrt-mixed", lambda, nullptr, nullptr);
  for (Eigen::Index i = 0; i < H.rows(); ++i) {
    H(i, i) += std::max(lambda * H(i, i), testConfig().lambda_min);
  }
  auto backwardError = [&](const VecXd& delta) {
    return (H * delta + b).norm() / (H.norm() * delta.norm() + b.norm());
  };
  const double eps_f = std::numeric_limits<float>::epsilon();
  EXPECT_LT(backwardError(mixed), 100 * eps_f);
  EXPECT_LT(backwardError(ref), 100 * std::numeric_limits<double>::epsilon());
  EXPECT_GT(backwardError(mixed), 1e3 * backwardError(ref));
}

// Runs a few frames so that the window is full and has a prior, then compares.
TEST(VoEquivalence, NullspaceAndSchurGiveTheSameStep) {
  const Scenario scenario(40);
  SlidingWindowEstimator<double> ns(testConfig(), Variant::parse("ns-qr-sqrt-f64"),
                                    rigFromCalib(scenario.calib), scenario.truth(0));
  for (int i = 0; i < 30; ++i) ASSERT_TRUE(ns.processFrame(scenario.stream.frames[i]).status.ok());
  // Same window, linearized once per elimination, the landmarks damped too: the LM step of all
  // variables for the same λ.
  auto step = [&](OptElimination elimination) {
    Linearization<double>::Options options;
    options.damp_landmarks = true;
    options.lambda_min = testConfig().lambda_min;
    const auto lin = makeLinearization<double>(elimination, options);
    lin->linearize(ns.window());
    EXPECT_TRUE(lin->eliminate().ok());
    LinearStep<double> s;
    EXPECT_TRUE(lin->solve(1e-4, &s).ok());
    return s.delta;
  };
  const VecXd step_ns = step(OptElimination::kNullspace), step_sc = step(OptElimination::kSchur);
  ASSERT_GT(step_ns.norm(), 0);
  EXPECT_LT((step_ns - step_sc).norm() / step_ns.norm(), 1e-8);
}

// marginalization.lost_landmarks (estimator_settings.h): on the same windows, "with-state" leaves
// the landmarks whose track ended in the window when no state is marginalized (VO: no keyframe),
// and otherwise plans exactly what "at-once" plans; the windows come from a with-state run, in
// which lost landmarks wait, and that run still recovers the truth from noise-free tracks.
TEST(VoMarginalization, LostLandmarksWaitForTheNextKeyframeMarginalizationWithState) {
  const Scenario scenario(60);
  EstimatorSettings with_state = testConfig();
  with_state.lost_landmarks = LostLandmarkMarg::kWithState;
  // The policies judge the window after its frame with one keyframe fewer allowed, so that a full
  // window plans a keyframe marginalization too.
  EstimatorSettings policy_with_state = with_state, policy_at_once = testConfig();
  policy_with_state.max_kfs = policy_at_once.max_kfs = with_state.max_kfs - 1;
  SlidingWindowEstimator<double> estimator(with_state, Variant::parse("sc-sc-sq-f64"),
                                           rigFromCalib(scenario.calib), scenario.truth(0));
  int waited = 0, with_keyframe = 0;
  for (const TrackFrame& frame : scenario.stream.frames) {
    const FrameResult result = estimator.processFrame(frame);
    ASSERT_TRUE(result.status.ok()) << result.status.toString();
    EXPECT_LT((result.p_est - scenario.truth(frame.t_ns).translation()).norm(), 1e-3);
    const Window<double>& w = estimator.window();
    const int64_t current = w.frames.rbegin()->first;
    std::vector<int64_t> lost;
    for (const auto& [id, lm] : w.landmarks) {
      if (lm.obs.count(current) == 0) lost.push_back(id);
    }
    const MargDecision a = MarginalizationPolicy<double>(policy_at_once).decide(w, current);
    const MargDecision b = MarginalizationPolicy<double>(policy_with_state).decide(w, current);
    EXPECT_EQ(a.plan.vars, b.plan.vars);
    if (b.plan.vars.empty()) {
      EXPECT_TRUE(b.plan.landmarks.empty());
      EXPECT_EQ(a.plan.landmarks, lost);
      waited += lost.empty() ? 0 : 1;
    } else {
      EXPECT_EQ(a.plan.landmarks, b.plan.landmarks);
      ++with_keyframe;
    }
  }
  EXPECT_GT(waited, 0);  // the case the key is about occurred
  EXPECT_GT(with_keyframe, 0);
}

TEST(VoEquivalence, QrAndSchurMarginalizationGiveTheSamePriorHessian) {
  const Scenario scenario(40);
  SlidingWindowEstimator<double> estimator(testConfig(), Variant::parse("ns-qr-sqrt-f64"),
                                           rigFromCalib(scenario.calib), scenario.truth(0));
  for (int i = 0; i < 30; ++i) {
    ASSERT_TRUE(estimator.processFrame(scenario.stream.frames[i]).status.ok());
  }
  const Window<double>& window = estimator.window();
  const MargPlan plan = MarginalizationPolicy<double>(window.config())
                            .keyframeMarginalization(window, estimator.keyframeIds().front());
  MatXd H_qr, H_sc;
  ASSERT_TRUE(
      trialMarginalization(window, estimator.shadowPrior(), plan, MargMethod::kQr, &H_qr).ok());
  ASSERT_TRUE(
      trialMarginalization(window, estimator.shadowPrior(), plan, MargMethod::kSchur, &H_sc).ok());
  ASSERT_GT(H_qr.norm(), 0);
  EXPECT_LT((H_qr - H_sc).norm() / H_qr.norm(), 1e-8);
}

// Hessian and square-root storage of the same Schur-complement prior are the same energy (the
// Hessian prior's constant is ½ bᵀH⁺b), so with pixel noise both take the same LM iterations and
// reach the same costs, frame after frame, up to rounding.
TEST(VoStorage, HessianAndSquareRootPriorsGiveTheSameCosts) {
  const Scenario scenario(80, true);
  auto run = [&](const char* name) {
    SlidingWindowEstimator<double> estimator(testConfig(), Variant::parse(name),
                                             rigFromCalib(scenario.calib), scenario.truth(0));
    std::vector<FrameResult> results;
    for (const TrackFrame& frame : scenario.stream.frames) {
      results.push_back(estimator.processFrame(frame));
      EXPECT_TRUE(results.back().status.ok()) << results.back().status.toString();
    }
    return results;
  };
  const std::vector<FrameResult> sq = run("sc-sc-sq-f64"), sqrt = run("sc-sc-sqrt-f64");
  ASSERT_EQ(sq.size(), sqrt.size());
  for (size_t i = 0; i < sq.size(); ++i) {
    EXPECT_EQ(sq[i].lm_iterations, sqrt[i].lm_iterations) << "frame " << i;
    EXPECT_NEAR(sq[i].cost_final, sqrt[i].cost_final, 1e-8 * sqrt[i].cost_final) << "frame " << i;
  }
}

// lm.stop_rule = basalt counts cost evaluations, not linearizations: with max_iterations = 1 the
// default rule linearizes once per frame, Basalt's rule allows max_iterations + 1 = 2 evaluations,
// so a frame whose first step is accepted without converging linearizes a second time. Both
// rules only ever accept cost decreases, and on noise-free tracks both recover the truth.
TEST(VoStopRule, BasaltRuleCountsEvaluationsAndRecoversTheTruth) {
  const Scenario noisy(60, true);
  auto run = [&](const Scenario& scenario, LmStopRule rule, int max_iterations, double* error) {
    EstimatorSettings config = testConfig();
    config.lm_stop_rule = rule;
    config.lm_max_iterations = max_iterations;
    SlidingWindowEstimator<double> estimator(config, Variant::parse("ns-qr-sqrt-f64"),
                                             rigFromCalib(scenario.calib), scenario.truth(0));
    std::vector<FrameResult> results;
    for (const TrackFrame& frame : scenario.stream.frames) {
      results.push_back(estimator.processFrame(frame));
      EXPECT_TRUE(results.back().status.ok()) << results.back().status.toString();
      EXPECT_LE(results.back().cost_final, results.back().cost_initial);
      *error = std::max(*error,
                        (results.back().p_est - scenario.truth(frame.t_ns).translation()).norm());
    }
    return results;
  };
  double error = 0;
  int second_linearizations = 0;
  for (const FrameResult& r : run(noisy, LmStopRule::kBasalt, 1, &error)) {
    EXPECT_GE(r.lm_iterations, 1);
    EXPECT_LE(r.lm_iterations, 2);
    second_linearizations += r.lm_iterations == 2 ? 1 : 0;
  }
  EXPECT_GT(second_linearizations, 0);
  for (const FrameResult& r : run(noisy, LmStopRule::kMarglab, 1, &error)) {
    EXPECT_EQ(r.lm_iterations, 1);
  }
  for (const FrameResult& r : run(noisy, LmStopRule::kBasalt, 7, &error)) {
    EXPECT_LE(r.lm_iterations, 8);
  }
  static const Scenario noise_free(200);
  double noise_free_error = 0;
  run(noise_free, LmStopRule::kBasalt, 7, &noise_free_error);
  EXPECT_LT(noise_free_error, 1e-3);
}

// The LM loop over landmark blocks in several threads: the same estimate as one thread up to the
// order of the sums, and the same bits in every run with the same thread count.
TEST(VoThreads, ThreadedLmLoopMatchesOneThreadAndIsReproducible) {
  const Scenario scenario(60);
  for (const char* name : {"ns-qr-sqrt-f64", "sc-sc-sq-f64"}) {
    auto run = [&](int threads) {
      EstimatorSettings config = testConfig();
      config.lm_threads = threads;
      SlidingWindowEstimator<double> estimator(config, Variant::parse(name),
                                               rigFromCalib(scenario.calib), scenario.truth(0));
      std::vector<double> out;
      for (const TrackFrame& frame : scenario.stream.frames) {
        const FrameResult result = estimator.processFrame(frame);
        EXPECT_TRUE(result.status.ok()) << result.status.toString();
        const Eigen::Vector3d p = result.p_est;
        out.insert(out.end(), {p.x(), p.y(), p.z(), result.cost_final});
      }
      return out;
    };
    const std::vector<double> one = run(1), three = run(3), again = run(3);
    ASSERT_EQ(one.size(), three.size());
    EXPECT_EQ(three, again) << name;
    for (size_t i = 0; i < one.size(); ++i) {
      EXPECT_NEAR(three[i], one[i], 1e-9 * std::max(1.0, std::abs(one[i]))) << name << " " << i;
    }
  }
}

TEST(VoGauge, GaugeFreePriorHasASixDimensionalNullspace) {
  const Scenario scenario(60);
  SlidingWindowEstimator<double> estimator(testConfig(), Variant::parse("ns-qr-sqrt-f64"),
                                           rigFromCalib(scenario.calib), scenario.truth(0));
  std::optional<MargEvent> last;
  for (const TrackFrame& frame : scenario.stream.frames) {
    FrameResult result = estimator.processFrame(frame);
    ASSERT_TRUE(result.status.ok());
    if (result.marg_event && result.marg_event->numPoses() >= 4) last = result.marg_event;
  }
  ASSERT_TRUE(last.has_value());
  const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<MatXd>(last->H_m).eigenvalues();
  const double scale = ev.cwiseAbs().maxCoeff();
  const double gauge = ev.head(6).cwiseAbs().maxCoeff();
  EXPECT_LT(gauge, 1e-9 * scale) << ev.transpose();
  // A clear gap to the observable directions.
  EXPECT_GT(ev[6], 1e4 * gauge) << ev.transpose();

  // ΔE_m (eq. 27) along the 6 gauge directions is tiny against the random direction.
  const PriorDiagnostics diagnostics =
      diagnoseSqrtPrior(last->J_m, last->r_m, last->layout, last->state, 11);
  for (int d = kGaugeX; d <= kGaugeYaw; ++d) {
    EXPECT_LT(std::abs(diagnostics.dEm[d]), 1e-6 * std::abs(diagnostics.dEm[kGaugeRandom]))
        << kGaugeDirectionNames[d] << ": " << diagnostics.dEm.transpose();
  }
}

// diagnostics.marg_rounding (marg_rounding.h) against independent computations, every event of a
// noisy run in each precision: the reference marginal through the Marginalizer itself
// (trialMarginalization on the window widened to double, the old prior promoted) gives the run's
// total error; the gauge information does not depend on the basis of the rigid motions (an SVD's
// instead of the QR's); f64 injects nothing.
template <typename Scalar>
void checkMargRounding(const char* variant_name) {
  const Scenario scenario(60, true);
  const Variant variant = Variant::parse(variant_name);
  SlidingWindowEstimator<Scalar> estimator(testConfig(), variant, rigFromCalib(scenario.calib),
                                           scenario.truth(0));
  int events = 0, with_poses = 0, translation_checked = 0;
  estimator.setMargObserver([&](const Window<Scalar>& w, const MargPlan& plan,
                                const MargPrior<Scalar>& before, const MargPrior<Scalar>& after) {
    MargRoundingRow row;
    ASSERT_TRUE(measureMargRounding(w, plan, before, after, variant, &row).ok());
    ++events;
    const Window<double> wd = restoredWindow<double>(snapshotOf(w), variant, w.config());
    MargPrior<double> before64;
    before64.storage = before.storage;
    for (const auto& block : before.blocks) {
      before64.addBlock(block.var, block.T0.template cast<double>(),
                        block.sb0.template cast<double>());
    }
    before64.setHessian(before.hessian.H.template cast<double>(),
                        before.hessian.b.template cast<double>(), before.hessian.c);
    MatXd H_ref;
    ASSERT_TRUE(trialMarginalization(wd, before64, plan, MargMethod::kSchur, &H_ref).ok());
    const MatXd H_run = after.hessian.H.template cast<double>();
    const double total = (H_run - H_ref).norm() / H_ref.norm();
    // Both are f64 computations of the same marginal (1e-12: far below any f32 rounding).
    EXPECT_NEAR(row.total.rel_fro, total, 1e-12 + 1e-6 * total);
    if (std::is_same_v<Scalar, double>) {
      EXPECT_EQ(row.total.rel_fro, 0.0);
      EXPECT_EQ(row.schur.rel_fro + row.add_prior.rel_fro + row.new_factors.rel_fro, 0.0);
    } else if (plan.vars.size() > 0) {
      ++with_poses;
      EXPECT_GT(row.total.rel_fro, 0.0);  // f32 rounds
      // Stored in f32, the marginal is at least its own rounding away, and the stages add up.
      EXPECT_GE(row.total.rel_fro,
                0.5 * row.floor_rel_fro);  // the stages may cancel part of the floor
      EXPECT_LE(row.total.rel_fro,
                row.new_factors.rel_fro + row.add_prior.rel_fro + row.schur.rel_fro + 1e-12);
    }
    // The gauge block in another orthonormal basis of the same 6 rigid motions.
    PriorLayout layout;
    GaugeState state;
    after.gaugeLayout(&layout, &state);
    const MatXd rigid = gaugeDirections(layout, after.cols(), state, 0).leftCols(6);
    const MatXd G = Eigen::JacobiSVD<MatXd>(rigid, Eigen::ComputeThinU).matrixU();
    const MatXd block = G.transpose() * (0.5 * (H_run + H_run.transpose())) * G;
    const double gauge_min = Eigen::SelfAdjointEigenSolver<MatXd>(block).eigenvalues()(0);
    const double scale =
        Eigen::SelfAdjointEigenSolver<MatXd>(H_run).eigenvalues().cwiseAbs().maxCoeff();
    EXPECT_NEAR(row.gauge_min_run, gauge_min, 1e-12 * scale);
    // The least information along a translation, in an SVD basis of the raw translations.
    const MatXd T = Eigen::JacobiSVD<MatXd>(rigid.leftCols(3), Eigen::ComputeThinU).matrixU();
    const MatXd t_block = T.transpose() * (0.5 * (H_ref + H_ref.transpose())) * T;
    EXPECT_NEAR(row.translation_min_ref,
                Eigen::SelfAdjointEigenSolver<MatXd>(t_block).eigenvalues()(0), 1e-12 * scale);
    EXPECT_GE(row.translation_min_ref, row.gauge_min_ref - 1e-12 * scale);  // a subspace of it
    ++translation_checked;
  });
  for (const TrackFrame& frame : scenario.stream.frames) {
    ASSERT_TRUE(estimator.processFrame(frame).status.ok());
  }
  EXPECT_GT(events, 20);
  EXPECT_GT(translation_checked, 10);
  if (std::is_same_v<Scalar, float>) {
    EXPECT_GE(with_poses, 3);  // keyframe events of 60 frames
  }
}

TEST(VoMargRounding, MatchesTheMarginalizerInDoubleF32) {
  checkMargRounding<float>("sc-sc-sq-f32");
}
TEST(VoMargRounding, InjectsNothingInF64) { checkMargRounding<double>("sc-sc-sq-f64"); }

// A run that is not a VO Schur marginalization of a plain Hessian prior is refused.
TEST(VoMargRounding, OtherStoragesAreRefused) {
  const Scenario scenario(10);
  SlidingWindowEstimator<double> estimator(testConfig(), Variant::parse("sc-sc-sqrt-f64"),
                                           rigFromCalib(scenario.calib), scenario.truth(0));
  int refused = 0;
  estimator.setMargObserver([&](const Window<double>& w, const MargPlan& plan,
                                const MargPrior<double>& before, const MargPrior<double>& after) {
    MargRoundingRow row;
    refused +=
        measureMargRounding(w, plan, before, after, Variant::parse("sc-sc-sqrt-f64"), &row).ok()
            ? 0
            : 1;
  });
  for (const TrackFrame& frame : scenario.stream.frames) {
    ASSERT_TRUE(estimator.processFrame(frame).status.ok());
  }
  EXPECT_GT(refused, 0);
}

}  // namespace
}  // namespace marglab
