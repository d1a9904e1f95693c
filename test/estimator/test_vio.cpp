// The VIO estimator through its public interface on the EuRoC MH_01 trajectory with noise-free
// simulated stereo tracks and a noise-free synthetic IMU: every variant tracks the truth, the
// gauge-free prior has the 4-dof VIO gauge (x, y, z, yaw) as its nullspace, and `qr` and `sc`
// marginalization give the same prior for each of the three marginalization policies.

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "core/diagnostics/diagnostics.h"
#include "core/estimator/estimator.h"
#include "estimator/variant_params.h"
#include "estimator/vio_scenario.h"

namespace marglab {
namespace {

using test::VioScenario;

const VioScenario& sixtySeconds() {
  static const VioScenario scenario(10.0, 60.0);
  return scenario;
}

class VioVariantTest : public ::testing::TestWithParam<std::string> {};

TEST_P(VioVariantTest, NoiseFreeSimulationTracksTheTruthToACentimetre) {
  const VioScenario& scenario = sixtySeconds();
  const Variant variant = Variant::parse(GetParam());
  ASSERT_EQ(variant.precision, Precision::kF64);
  EstimatorSettings config;
  SlidingWindowEstimator<double> estimator =
      scenario.estimator<double>(variant, config, test::kWithoutShadowPrior);
  double max_error = 0;
  for (const TrackFrame& frame : scenario.stream.frames) {
    const FrameResult result = estimator.processFrame(frame);
    ASSERT_TRUE(result.status.ok()) << result.status.toString();
    max_error = std::max(max_error, (result.p_est - scenario.truePosition(frame.t_ns)).norm());
  }
  EXPECT_GT(scenario.stream.frames.size(), 590u);
  EXPECT_LT(max_error, 0.01);
}

INSTANTIATE_TEST_SUITE_P(F64, VioVariantTest, test::doublePrecisionVariants(),
                         test::variantTestName);

TEST(VioGauge, GaugeFreePriorHasTheFourDofVioGauge) {
  const VioScenario scenario(10.0, 12.0);
  SlidingWindowEstimator<double> estimator =
      scenario.estimator<double>(Variant::parse("ns-qr-sqrt-f64"));
  std::optional<MargEvent> last;
  for (const TrackFrame& frame : scenario.stream.frames) {
    FrameResult result = estimator.processFrame(frame);
    ASSERT_TRUE(result.status.ok()) << result.status.toString();
    if (result.marg_event && result.marg_event->numPoses() >= 6) last = result.marg_event;
  }
  ASSERT_TRUE(last.has_value());
  const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<MatXd>(last->H_m).eigenvalues();
  const double scale = ev.cwiseAbs().maxCoeff();
  const double gauge = ev.head(4).cwiseAbs().maxCoeff();
  EXPECT_LT(gauge, 1e-9 * scale) << ev.transpose();
  EXPECT_GT(ev[4], 1e4 * gauge) << ev.transpose();  // a clear gap to the observable directions

  const PriorDiagnostics diagnostics =
      diagnoseSqrtPrior(last->J_m, last->r_m, last->layout, last->state, 11);
  const double observable =
      std::min({std::abs(diagnostics.dEm[kGaugeRoll]), std::abs(diagnostics.dEm[kGaugePitch]),
                std::abs(diagnostics.dEm[kGaugeRandom])});
  for (int d : {kGaugeX, kGaugeY, kGaugeZ, kGaugeYaw}) {
    EXPECT_LT(std::abs(diagnostics.dEm[d]), 1e-6 * observable)
        << kGaugeDirectionNames[d] << ": " << diagnostics.dEm.transpose();
  }
}

// qr (flat QR on landmark Q2ᵀ rows, IMU rows and prior rows) and sc (Schur complement with a
// pseudo-inverse) give the same prior Hessian on the same window, for each policy.
TEST(VioEquivalence, QrAndSchurMarginalizationAgreeForEveryPolicy) {
  const VioScenario scenario(10.0, 12.0);
  SlidingWindowEstimator<double> estimator =
      scenario.estimator<double>(Variant::parse("ns-qr-sqrt-f64"));
  const Window<double>& window = estimator.window();
  const MarginalizationPolicy<double> policy(window.config());
  auto compare = [&](const MargPlan& plan, const char* what) {
    MatXd H_qr, H_sc;
    const MargPrior<double>& shadow = estimator.shadowPrior();
    ASSERT_TRUE(trialMarginalization(window, shadow, plan, MargMethod::kQr, &H_qr).ok()) << what;
    ASSERT_TRUE(trialMarginalization(window, shadow, plan, MargMethod::kSchur, &H_sc).ok()) << what;
    ASSERT_GT(H_qr.norm(), 0) << what;
    EXPECT_LT((H_qr - H_sc).norm() / H_qr.norm(), 1e-8) << what;
  };
  bool tested_kf_state = false, tested_frame_state = false, tested_keyframe = false;
  for (const TrackFrame& frame : scenario.stream.frames) {
    ASSERT_TRUE(estimator.processFrame(frame).status.ok());
    if (estimator.shadowPrior().empty()) continue;
    if (const auto plan = policy.stateMarginalization(window, true)) {
      const int64_t oldest = plan->vars.begin()->frame_id;
      bool& tested = estimator.isKeyframe(oldest) ? tested_kf_state : tested_frame_state;
      if (!tested) {
        compare(*plan, estimator.isKeyframe(oldest) ? "keyframe state" : "non-keyframe state");
        tested = true;
      }
    }
    const std::vector<int64_t> kfs = estimator.keyframeIds();
    const std::vector<int64_t> states = estimator.stateIds();
    if (!tested_keyframe && kfs.size() >= 5 && kfs.front() < states.front()) {
      compare(policy.keyframeMarginalization(window, kfs.front()), "keyframe pose");
      tested_keyframe = true;
    }
  }
  EXPECT_TRUE(tested_kf_state && tested_frame_state && tested_keyframe);
}

}  // namespace
}  // namespace marglab
