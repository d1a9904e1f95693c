// The keyframe marginalization strategies (Hsiung et al., IROS 2018; config
// marginalization.strategy) through the estimator's public interface on noise-free MH_01: `dense`
// keeps the estimate of a batch solve over the same measurements, `nfr` replaces every dense prior
// by recovered factors with a finite, non-negative KLD and fewer non-zeros, and the strategy is a
// validated config key.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "core/common/error.h"
#include "estimator/vio_scenario.h"

namespace marglab {
namespace {

using test::VioScenario;

const VioScenario& fifteenSeconds() {
  static const VioScenario scenario(10.0, 15.0);
  return scenario;
}

const VioScenario& fourSeconds() {
  static const VioScenario scenario(10.0, 4.0, 10000.0);
  return scenario;
}

template <typename Scalar>
std::map<int64_t, SE3<double>> finalPoses(const SlidingWindowEstimator<Scalar>& estimator) {
  std::map<int64_t, SE3<double>> poses;
  for (const auto& frame : estimator.snapshot().frames) poses[frame.t_ns] = frame.T_w_i;
  return poses;
}

// Same measurements: every frame is a keyframe, so the mid-frame marginalization (which drops a
// non-keyframe's observations) never happens. Converged far below the comparison bounds (the
// default stopping rules stop at 1e-4 steps).
EstimatorSettings everyFrameAKeyframe(MargStrategy strategy) {
  EstimatorSettings config;
  config.marg_strategy = strategy;
  config.kf_connected_ratio = 2.0;  // connected < 2 · observed: every frame
  config.min_frames_after_kf = 1;
  config.lm_max_iterations = 30;
  config.stop_relative_cost = 1e-15;
  config.stop_max_step = 1e-10;
  return config;
}

std::map<int64_t, SE3<double>> runToTheEnd(const VioScenario& scenario, const Variant& variant,
                                           const EstimatorSettings& config, int* sparsify_events) {
  SlidingWindowEstimator<double> estimator =
      scenario.estimator<double>(variant, config, test::kWithoutShadowPrior);
  for (const TrackFrame& frame : scenario.stream.frames) {
    const FrameResult result = estimator.processFrame(frame);
    EXPECT_TRUE(result.status.ok()) << result.status.toString();
    if (result.sparsify_event) {
      ++*sparsify_events;
      EXPECT_FALSE(result.sparsify_event->recovered);
      EXPECT_GT(result.sparsify_event->n_blanket_landmarks, 0);
    }
  }
  return finalPoses(estimator);
}

double maxPositionDifference(const std::map<int64_t, SE3<double>>& window,
                             const std::map<int64_t, SE3<double>>& reference) {
  double max_diff = 0;
  for (const auto& [t_ns, T] : window) {
    max_diff = std::max(max_diff, (T.translation() - reference.at(t_ns).translation()).norm());
  }
  return max_diff;
}

class DenseStrategyTest : public ::testing::TestWithParam<std::string> {};

// Batch: a window that never marginalizes, over the same measurements. Marginalization at fixed
// linearization points is exact for consistent measurements; the noise-free measurements are
// consistent up to the synthetic IMU's discretization (4 s at 10 kHz: the estimates are ~5e-5 m
// from the truth). dense then differs from the batch at second order in that inconsistency
// (1.6e-6 m; 8e-5 m with a 1 kHz IMU), discard — which drops the keyframe's observations of the
// landmarks that stay — at first order (4.7e-5 m; 4.8e-4 m at 1 kHz).
TEST_P(DenseStrategyTest, KeepsTheEstimateOfABatchSolve) {
  const VioScenario& scenario = fourSeconds();
  const Variant variant = Variant::parse(GetParam());
  int events = 0;
  const auto dense =
      runToTheEnd(scenario, variant, everyFrameAKeyframe(MargStrategy::kDense), &events);
  EXPECT_GT(events, 20);

  static const std::map<int64_t, SE3<double>> batch = [&scenario] {
    EstimatorSettings config = everyFrameAKeyframe(MargStrategy::kDense);
    config.max_kfs = 100000;
    config.max_states = 100000;
    int none = 0;
    return runToTheEnd(scenario, Variant::parse("ns-qr-sqrt-f64"), config, &none);
  }();
  static const std::map<int64_t, SE3<double>> discard = [&scenario] {
    int none = 0;
    return runToTheEnd(scenario, Variant::parse("ns-qr-sqrt-f64"),
                       everyFrameAKeyframe(MargStrategy::kDiscard), &none);
  }();
  ASSERT_EQ(batch.size(), scenario.stream.frames.size());
  const double dense_diff = maxPositionDifference(dense, batch);
  const double discard_diff = maxPositionDifference(discard, batch);
  EXPECT_LT(dense_diff, 5e-6);
  EXPECT_LT(dense_diff, 0.1 * discard_diff) << "discard: " << discard_diff;
}

INSTANTIATE_TEST_SUITE_P(F64, DenseStrategyTest,
                         ::testing::Values("ns-qr-sqrt-f64", "sc-sc-sq-f64"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string name = info.param;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

// With rigid deflation (rigid_tol > 0): along x … yaw the factors carry at most the dense prior's
// information (to rigid_tol relative: the pose–landmark factors' invariance holds to rounding), and
// exactly as much at some events (core/sparsify/rigid_deflation.h: wherever every rigid direction
// had an excess).
template <typename Scalar>
void expectRecoveredEvents(const Variant& variant, double max_position_error_m,
                           SparsifyTopology topology = SparsifyTopology::kPaper,
                           double rigid_tol = 0) {
  const VioScenario& scenario = fifteenSeconds();
  EstimatorSettings config;
  config.marg_strategy = MargStrategy::kNfr;
  config.nfr_topology = topology;
  config.nfr_rigid_deflation = rigid_tol > 0;
  int matched_events = 0;
  SlidingWindowEstimator<Scalar> estimator =
      scenario.estimator<Scalar>(variant, config, test::kWithoutShadowPrior);
  int events = 0;
  double max_error = 0;
  for (const TrackFrame& frame : scenario.stream.frames) {
    const FrameResult result = estimator.processFrame(frame);
    ASSERT_TRUE(result.status.ok()) << result.status.toString();
    max_error = std::max(max_error, (result.p_est - scenario.truePosition(frame.t_ns)).norm());
    if (!result.sparsify_event) continue;
    const SparsifyEvent& event = *result.sparsify_event;
    ++events;
    ASSERT_TRUE(event.recovered) << event.fallback_reason;
    EXPECT_TRUE(std::isfinite(event.kld));
    EXPECT_GE(event.kld, 0.0);
    EXPECT_LT(event.nnz_sparse, event.nnz_dense);
    // Information along the gauge directions: of the dense prior finite, of the recovered factors
    // (fitted to the regularized Λ_t + εI) positive.
    EXPECT_TRUE(event.info_dense.allFinite());
    EXPECT_TRUE((event.info_sparse.array() > 0.0).all()) << event.info_sparse.transpose();
    if (rigid_tol > 0) {
      const auto ratio = (event.info_sparse.array() / event.info_dense.array()).head<6>();
      EXPECT_TRUE((ratio <= 1 + rigid_tol).all()) << ratio.transpose();
      matched_events += ((ratio - 1).abs() <= rigid_tol).all() ? 1 : 0;
    }
    // The factors replace the prior (joint-states: all but the joint state factor).
    if (topology != SparsifyTopology::kJointStates) {
      EXPECT_TRUE(estimator.prior().empty());
    } else {
      EXPECT_FALSE(estimator.prior().empty());
      EXPECT_FALSE(estimator.prior().hasLandmarks());
    }
  }
  EXPECT_GT(events, 5);
  EXPECT_LT(max_error, max_position_error_m);
  if (rigid_tol > 0) {
    EXPECT_GT(matched_events, 0);
  }
}

TEST(NfrStrategy, EveryKeyframeEventIsSparsifiedQrF64) {
  expectRecoveredEvents<double>(Variant::parse("ns-qr-sqrt-f64"), 0.01);
}
TEST(NfrStrategy, EveryKeyframeEventIsSparsifiedSchurF64) {
  expectRecoveredEvents<double>(Variant::parse("sc-sc-sq-f64"), 0.01);
}
TEST(NfrStrategy, EveryKeyframeEventIsSparsifiedQrF32) {
  expectRecoveredEvents<float>(Variant::parse("ns-qr-sqrt-f32"), 0.05);
}

TEST(NfrStrategy, JointStatesTopologyQrF64) {
  expectRecoveredEvents<double>(Variant::parse("ns-qr-sqrt-f64"), 0.01,
                                SparsifyTopology::kJointStates);
}
TEST(NfrStrategy, JointStatesTopologySchurF64) {
  expectRecoveredEvents<double>(Variant::parse("sc-sc-sq-f64"), 0.01,
                                SparsifyTopology::kJointStates);
}

TEST(NfrStrategy, RelativePoseTopologyQrF64) {
  expectRecoveredEvents<double>(Variant::parse("ns-qr-sqrt-f64"), 0.01,
                                SparsifyTopology::kRelativePose);
}
TEST(NfrStrategy, RelativePoseTopologySchurF64) {
  expectRecoveredEvents<double>(Variant::parse("sc-sc-sq-f64"), 0.01,
                                SparsifyTopology::kRelativePose);
}

TEST(NfrStrategy, RigidDeflationQrF64) {
  expectRecoveredEvents<double>(Variant::parse("ns-qr-sqrt-f64"), 0.01, SparsifyTopology::kPaper,
                                1e-6);
}
TEST(NfrStrategy, RigidDeflationSchurF64) {
  expectRecoveredEvents<double>(Variant::parse("sc-sc-sq-f64"), 0.01, SparsifyTopology::kPaper,
                                1e-6);
}
TEST(NfrStrategy, RigidDeflationQrF32) {
  expectRecoveredEvents<float>(Variant::parse("ns-qr-sqrt-f32"), 0.05, SparsifyTopology::kPaper,
                               1e-3);
}

// On the same dense prior (the first keyframe event: both runs are identical until then) the joint
// state factor can represent everything the unary factors can, so its KLD is lower.
TEST(NfrStrategy, JointStatesLoseLessInformationThanThePaperTopology) {
  const VioScenario& scenario = fifteenSeconds();
  auto firstKld = [&scenario](SparsifyTopology topology) {
    EstimatorSettings config;
    config.marg_strategy = MargStrategy::kNfr;
    config.nfr_topology = topology;
    SlidingWindowEstimator<double> estimator = scenario.estimator<double>(
        Variant::parse("ns-qr-sqrt-f64"), config, test::kWithoutShadowPrior);
    for (const TrackFrame& frame : scenario.stream.frames) {
      const FrameResult result = estimator.processFrame(frame);
      EXPECT_TRUE(result.status.ok()) << result.status.toString();
      if (result.sparsify_event) return result.sparsify_event->kld;
    }
    return std::numeric_limits<double>::quiet_NaN();
  };
  const double paper = firstKld(SparsifyTopology::kPaper);
  const double joint = firstKld(SparsifyTopology::kJointStates);
  ASSERT_TRUE(std::isfinite(paper) && std::isfinite(joint)) << paper << " " << joint;
  EXPECT_GE(joint, 0.0);
  EXPECT_LT(joint, paper);
}

TEST(MargStrategyConfig, IsAValidatedConfigKey) {
  RunConfig config;
  EXPECT_EQ(config.estimator.marg_strategy, MargStrategy::kDiscard);
  config.loadTomlString("[marginalization]\nstrategy = \"nfr\"\n", "test.toml");
  EXPECT_EQ(config.estimator.marg_strategy, MargStrategy::kNfr);
  RunConfig round_trip;
  round_trip.loadTomlString(config.toToml(), "round_trip.toml");
  EXPECT_EQ(round_trip.estimator.marg_strategy, MargStrategy::kNfr);
  config.loadTomlString("[marginalization]\nnfr_topology = \"joint-states\"\n", "test.toml");
  EXPECT_EQ(config.estimator.nfr_topology, SparsifyTopology::kJointStates);
  config.loadTomlString("[marginalization]\nnfr_topology = \"relative-pose\"\n", "test.toml");
  EXPECT_EQ(config.estimator.nfr_topology, SparsifyTopology::kRelativePose);
  round_trip.loadTomlString(config.toToml(), "round_trip.toml");
  EXPECT_EQ(round_trip.estimator.nfr_topology, SparsifyTopology::kRelativePose);
  try {
    config.loadTomlString("[marginalization]\nnfr_topology = \"tree\"\n", "bad.toml");
    FAIL() << "an unknown topology was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.toml:2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("relative-pose"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(config.estimator.nfr_rigid_deflation);
  config.loadTomlString("[marginalization]\nnfr_rigid_deflation = true\n", "test.toml");
  EXPECT_TRUE(config.estimator.nfr_rigid_deflation);
  EXPECT_THROW(config.validate(), InputError);  // topology relative-pose: see below
  config.loadTomlString("[marginalization]\nnfr_topology = \"paper\"\n", "test.toml");
  EXPECT_NO_THROW(config.validate());
  round_trip.loadTomlString(config.toToml(), "round_trip.toml");
  EXPECT_TRUE(round_trip.estimator.nfr_rigid_deflation);
  try {
    config.loadTomlString("[marginalization]\nnfr_rigid_deflation = \"yes\"\n", "bad.toml");
    FAIL() << "a non-boolean nfr_rigid_deflation was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("nfr_rigid_deflation"), std::string::npos) << e.what();
  }
  // Deflation acts on the paper topology's unary factors: not with discard / dense, nor with the
  // other topologies.
  for (const char* bad : {"strategy = \"discard\"", "strategy = \"dense\"",
                          "nfr_topology = \"joint-states\"", "nfr_topology = \"relative-pose\""}) {
    RunConfig relation = config;
    relation.loadTomlString(std::string("[marginalization]\n") + bad + "\n", "bad.toml");
    try {
      relation.validate();
      FAIL() << "nfr_rigid_deflation accepted with " << bad;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("nfr_rigid_deflation"), std::string::npos) << e.what();
    }
  }
  try {
    config.loadTomlString("[marginalization]\n\nstrategy = \"sparse\"\n", "bad.toml");
    FAIL() << "an unknown strategy was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.toml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(":3"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("nfr"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace marglab
