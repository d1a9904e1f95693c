// The VIO estimator through its public interface on the EuRoC MH_01 trajectory with noise-free
// simulated stereo tracks and a noise-free synthetic IMU: every variant tracks the truth, the
// gauge-free prior has the 4-dof VIO gauge (x, y, z, yaw) as its nullspace, and `qr` and `sc`
// marginalization give the same prior for each of the three marginalization policies.

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "core/data/sequence.h"
#include "core/diagnostics/diagnostics.h"
#include "core/estimator/estimator.h"
#include "core/estimator/run.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/imu_synth.h"
#include "core/sim/trajectory_spline.h"
#include "estimator/variant_params.h"

namespace marglab {
namespace {

// MH_01 from t_begin_s for duration_s, cameras at 10 Hz (every other EuRoC frame, to keep the
// test fast), tracks and IMU without noise or outliers.
constexpr double kImuRateHz = 1000.0;

struct VioScenario {
  Sequence sequence;
  TrajectorySpline spline;
  TrackStream stream;
  ImuSetup imu;

  VioScenario(double t_begin_s, double duration_s)
      : sequence(loadSequence("euroc/MH_01_easy")),
        spline(TrajectorySpline::fromSequence(sequence)) {
    const int64_t t0 = spline.startTimeNs() + static_cast<int64_t>(t_begin_s * 1e9);
    const int64_t t1 = t0 + static_cast<int64_t>(duration_s * 1e9);
    std::vector<int64_t> cams;
    for (size_t k = 0; k < sequence.cam_t_ns.size(); k += 2) {
      if (sequence.cam_t_ns[k] >= t0 && sequence.cam_t_ns[k] <= t1) {
        cams.push_back(sequence.cam_t_ns[k]);
      }
    }
    sequence.cam_t_ns = cams;
    SimulationOptions options = defaultSimulationOptions(sequence, 3);
    options.tracker.noise = false;
    options.tracker.outliers = false;
    stream = simulateSequence(sequence, spline, options);
    imu.noise = sequence.imu_noise;
    imu.g_w = gravityWorld(DatasetKind::kEuroc);
    ImuSynthOptions synth = ImuSynthOptions::noiseFree();
    synth.gravity_w = imu.g_w;
    imu.imu = synthesizeImu(spline, imu.noise, kImuRateHz, 5, synth).imu;
    imu.sample_period_s = 1.0 / kImuRateHz;
    const TrajectorySample s = spline.evaluate(stream.frames.front().t_ns);
    imu.initial.t_ns = stream.frames.front().t_ns;
    imu.initial.T_w_i = SE3<double>(s.R_w_b, s.p_w_b);
    imu.initial.v_w = s.v_w;
  }
  Eigen::Vector3d truePosition(int64_t t_ns) const { return spline.evaluate(t_ns).p_w_b; }
  template <typename Scalar>
  SlidingWindowEstimator<Scalar> estimator(const Variant& variant,
                                           const EstimatorConfig& config = {}) const {
    EstimatorConfig c = config;
    c.min_frames_after_kf = 3;  // 5 at 20 Hz
    return SlidingWindowEstimator<Scalar>(c, variant, rigFromCalib(sequence.calib),
                                          imu.initial.T_w_i, imu);
  }
};

const VioScenario& sixtySeconds() {
  static const VioScenario scenario(10.0, 60.0);
  return scenario;
}

class VioVariantTest : public ::testing::TestWithParam<std::string> {};

TEST_P(VioVariantTest, NoiseFreeSimulationTracksTheTruthToACentimetre) {
  const VioScenario& scenario = sixtySeconds();
  const Variant variant = Variant::parse(GetParam());
  ASSERT_EQ(variant.precision, Precision::kF64);
  EstimatorConfig config;
  config.diagnostics = false;
  SlidingWindowEstimator<double> estimator = scenario.estimator<double>(variant, config);
  double max_error = 0;
  for (const TrackFrame& frame : scenario.stream.frames) {
    const FrameResult result = estimator.processFrame(frame);
    ASSERT_TRUE(result.status.ok()) << result.status.toString();
    max_error = std::max(max_error,
                         (result.T_w_i.translation() - scenario.truePosition(frame.t_ns)).norm());
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
  auto compare = [&](const MargPlan& plan, const char* what) {
    MatXd H_qr, H_sc;
    ASSERT_TRUE(estimator.trialMarginalization(plan, MargMethod::kQr, &H_qr).ok()) << what;
    ASSERT_TRUE(estimator.trialMarginalization(plan, MargMethod::kSchur, &H_sc).ok()) << what;
    ASSERT_GT(H_qr.norm(), 0) << what;
    EXPECT_LT((H_qr - H_sc).norm() / H_qr.norm(), 1e-8) << what;
  };
  bool tested_kf_state = false, tested_frame_state = false, tested_keyframe = false;
  for (const TrackFrame& frame : scenario.stream.frames) {
    ASSERT_TRUE(estimator.processFrame(frame).status.ok());
    if (estimator.shadowPrior().empty()) continue;
    if (const auto plan = estimator.planStateMarginalization(true)) {
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
      compare(estimator.planKeyframeMarginalization(kfs.front()), "keyframe pose");
      tested_keyframe = true;
    }
  }
  EXPECT_TRUE(tested_kf_state && tested_frame_state && tested_keyframe);
}

}  // namespace
}  // namespace marglab
