// The preconditioned Hessian storages sqp / sqj (docs/preconditioned_storage.md): the variant
// names, the stored prior as the same function as the unscaled Hessian prior, and whole runs —
// in double the same trajectory as `sq`, in single precision a run that tracks the truth.

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include <Eigen/Eigenvalues>

#include "core/common/error.h"
#include "core/estimator/marg_prior.h"
#include "estimator/vio_scenario.h"

namespace marglab {
namespace {

constexpr PriorStorage kHessianBlockJacobi{Representation::kHessian, Preconditioning::kBlockJacobi};
constexpr PriorStorage kHessianJacobi{Representation::kHessian, Preconditioning::kJacobi};

TEST(PreconditionedStorage, VariantNamesRoundTrip) {
  for (const char* name :
       {"sc-sc-sqp-f32", "ns-sc-sqp-f32", "sc-sc-sqj-f32", "sc-sc-sqp-f64", "sc-sc-sqrtp-f32"}) {
    EXPECT_EQ(Variant::parse(name).name(), name);
  }
  EXPECT_EQ(Variant::parse("sc-sc-sqp-f32").storage, kHessianBlockJacobi);
  EXPECT_EQ(Variant::parse("sc-sc-sqj-f32").storage, kHessianJacobi);
  EXPECT_EQ(Variant::parse("sc-sc-sqrtp-f32").storage,
            (PriorStorage{Representation::kSqrt, Preconditioning::kBlockJacobi}));
  // qr marginalization produces a square-root prior.
  EXPECT_THROW(Variant::parse("ns-qr-sqp-f32"), UsageError);
  EXPECT_THROW(Variant::parse("ns-qr-sqrtp-f32"), UsageError);
  EXPECT_THROW(Variant::parse("sc-sc-sqx-f32"), UsageError);
}

// A pose + speed-bias prior with an ill-scaled random Hessian, stored unscaled (sq) and
// preconditioned (sqp, sqj): E_m, its gradient and Hessian and the cost change along a step agree.
template <typename Scalar>
void expectSameFunction(const PriorStorage& storage) {
  std::mt19937_64 rng(41);
  std::normal_distribution<double> normal;
  MargPrior<Scalar> plain;
  plain.storage = {Representation::kHessian};
  plain.addBlock({1, StateBlock::kPose}, SE3<Scalar>(), Vec<Scalar, kSpeedBiasDim>::Zero());
  plain.addBlock({1, StateBlock::kSpeedBias}, SE3<Scalar>(), Vec<Scalar, kSpeedBiasDim>::Zero());
  const int n = plain.cols();
  MatXd J(2 * n, n);
  for (int i = 0; i < J.size(); ++i) J.data()[i] = normal(rng);
  const double unit[5] = {1.0, 10.0, 0.1, 1e3, 1e4};  // t, φ, v, b_g, b_a
  for (int k = 0; k < 5; ++k) J.middleCols(3 * k, 3) *= unit[k];
  const MatXd H = J.transpose() * J;
  const VecXd b = J.transpose() * VecXd::Ones(2 * n);
  plain.setHessian(H.cast<Scalar>(), b.cast<Scalar>(), Scalar(2));
  MargPrior<Scalar> scaled = plain;
  scaled.storage = storage;
  scaled.precondition();
  ASSERT_TRUE(scaled.scaled());

  VecX<Scalar> d(n), step(n);
  for (int i = 0; i < n; ++i) {
    d[i] = static_cast<Scalar>(1e-2 * normal(rng) / unit[i / 3]);
    step[i] = static_cast<Scalar>(1e-3 * normal(rng) / unit[i / 3]);
  }
  // Relative to the terms' magnitudes: a few roundings of 15-term sums.
  const double tol = 100 * static_cast<double>(NumericTraits<Scalar>::kEpsilon);
  const double cost = static_cast<double>(plain.cost(d));
  EXPECT_NEAR(static_cast<double>(scaled.cost(d)), cost, tol * std::abs(cost));
  MatX<Scalar> H_a, H_b;
  VecX<Scalar> b_a, b_b;
  plain.linearize(d, &H_a, &b_a);
  scaled.linearize(d, &H_b, &b_b);
  EXPECT_LE((H_b - H_a).template cast<double>().norm(), tol * H_a.template cast<double>().norm());
  EXPECT_LE(
      (b_b - b_a).template cast<double>().norm(),
      tol * (H_a.template cast<double>().norm() * d.template cast<double>().norm() + b.norm()));
  const double change = static_cast<double>(plain.costChange(d, step));
  EXPECT_NEAR(static_cast<double>(scaled.costChange(d, step)), change, tol * cost);
  EXPECT_LE((scaled.hessianAtAnchor() - H.cast<Scalar>()).template cast<double>().norm(),
            tol * H.norm());
}

TEST(PreconditionedStorage, StoredPriorIsTheSameFunctionF32) {
  expectSameFunction<float>(kHessianBlockJacobi);
  expectSameFunction<float>(kHessianJacobi);
}

TEST(PreconditionedStorage, StoredPriorIsTheSameFunctionF64) {
  expectSameFunction<double>(kHessianBlockJacobi);
  expectSameFunction<double>(kHessianJacobi);
}

// Runs the scenario, returns the largest position error; every frame must succeed.
// min_eigen (may be null): the most negative λ_min / trace of the stored prior's Hessian over the
// frames (double eigendecomposition of the stored matrix).
template <typename Scalar>
double maxPositionError(const test::VioScenario& scenario, const char* variant,
                        std::vector<Eigen::Vector3d>* positions = nullptr,
                        bool psd_hessian_prior = false, double* min_eigen = nullptr) {
  EstimatorSettings config;
  config.psd_hessian_prior = psd_hessian_prior;
  SlidingWindowEstimator<Scalar> estimator =
      scenario.estimator<Scalar>(Variant::parse(variant), config, test::kWithoutShadowPrior);
  double max_error = 0;
  for (const TrackFrame& frame : scenario.stream.frames) {
    const FrameResult result = estimator.processFrame(frame);
    EXPECT_TRUE(result.status.ok()) << variant << ": " << result.status.toString();
    if (!result.status.ok()) return std::numeric_limits<double>::infinity();
    if (positions != nullptr) positions->push_back(result.p_est);
    if (min_eigen != nullptr && !estimator.prior().empty()) {
      const MatXd H = estimator.prior().hessianAtAnchor().template cast<double>();
      const double lambda_min = Eigen::SelfAdjointEigenSolver<MatXd>(H).eigenvalues()(0);
      *min_eigen = std::min(*min_eigen, lambda_min / H.trace());
    }
    max_error = std::max(max_error, (result.p_est - scenario.truePosition(frame.t_ns)).norm());
  }
  return max_error;
}

// In double the preconditioning is a change of variables and nothing else: the sqp / sqj runs
// follow the sq run, the sqrtp run the sqrt run, to rounding.
TEST(PreconditionedStorage, DoublePrecisionRunsFollowTheHessianStorage) {
  const test::VioScenario scenario(10.0, 12.0);
  std::vector<Eigen::Vector3d> sq, sqp, sqj;
  maxPositionError<double>(scenario, "sc-sc-sq-f64", &sq);
  maxPositionError<double>(scenario, "sc-sc-sqp-f64", &sqp);
  maxPositionError<double>(scenario, "sc-sc-sqj-f64", &sqj);
  ASSERT_EQ(sq.size(), sqp.size());
  ASSERT_EQ(sq.size(), sqj.size());
  for (size_t i = 0; i < sq.size(); ++i) {
    EXPECT_LT((sqp[i] - sq[i]).norm(), 1e-6) << i;
    EXPECT_LT((sqj[i] - sq[i]).norm(), 1e-6) << i;
  }
  std::vector<Eigen::Vector3d> sqrt, sqrtp;
  maxPositionError<double>(scenario, "sc-sc-sqrt-f64", &sqrt);
  maxPositionError<double>(scenario, "sc-sc-sqrtp-f64", &sqrtp);
  ASSERT_EQ(sqrt.size(), sqrtp.size());
  // The square root is the LDLT of the new prior with negative pivots clamped; at the first
  // marginalizations the f64 prior's κ over its observable directions is ≈ 3e16 > 1/ε_f64
  // (docs/preconditioned_storage.md §3), so which pivots are clamped depends on the scaling:
  // 1.2 µm here, against 0.3 nm between the unclamped sq and sqrt. Bound: 10 µm, 1e-3 of the
  // 1 cm these runs keep to the truth.
  for (size_t i = 0; i < sqrt.size(); ++i) EXPECT_LT((sqrtp[i] - sqrt[i]).norm(), 1e-5) << i;
}

TEST(PreconditionedStorage, SinglePrecisionRunTracksTheTruth) {
  const test::VioScenario scenario(10.0, 12.0);
  EXPECT_GT(scenario.stream.frames.size(), 100u);
  EXPECT_LT(maxPositionError<float>(scenario, "sc-sc-sqp-f32"), 0.05);
  EXPECT_LT(maxPositionError<float>(scenario, "ns-sc-sqp-f32"), 0.05);
  EXPECT_LT(maxPositionError<float>(scenario, "sc-sc-sqrtp-f32"), 0.05);
}

// [marginalization] psd_hessian_prior (README item 5's isolating run): with each new prior stored
// as the Hessian of its clamped LDLT square root, the f32 Hessian storages run through the scenario
// and every stored prior is positive semidefinite to the rounding of forming JᵀJ in float
// (|λ_min| ≤ n·ε·trace, n ≤ 30 prior columns here). Whether sc-sc-sq-f32 fails here *without* the
// option depends on the compiler's rounding (GCC's build: within the first seconds; Clang's
// sanitizer build: not), so that contrast is not asserted; the whole runs of
// results/preconditioned (psd_sK against whole_sK) measure it.
TEST(PsdHessianPrior, StoredF32PriorIsPositiveSemidefiniteAndTheRunHolds) {
  const test::VioScenario scenario(10.0, 12.0);
  const double bound = 30 * NumericTraits<float>::kEpsilon;
  for (const char* variant : {"sc-sc-sq-f32", "sc-sc-sqp-f32"}) {
    SCOPED_TRACE(variant);
    double min_eigen = 0;
    EXPECT_LT(maxPositionError<float>(scenario, variant, nullptr, true, &min_eigen), 0.05);
    EXPECT_GE(min_eigen, -bound);
  }
}

// In double the projection changes the prior by rounding only: the runs follow the plain ones.
TEST(PsdHessianPrior, DoublePrecisionRunsFollowThePlainHessianStorage) {
  const test::VioScenario scenario(10.0, 12.0);
  for (const char* variant : {"sc-sc-sq-f64", "sc-sc-sqp-f64"}) {
    SCOPED_TRACE(variant);
    std::vector<Eigen::Vector3d> plain, psd;
    maxPositionError<double>(scenario, variant, &plain);
    maxPositionError<double>(scenario, variant, &psd, true);
    ASSERT_EQ(plain.size(), psd.size());
    for (size_t i = 0; i < plain.size(); ++i) EXPECT_LT((psd[i] - plain[i]).norm(), 1e-6) << i;
  }
}

// The config key is the psd axis c: `sc-sc-sq-f32` + psd_hessian_prior runs `sc-sc-sqc-f32` bit
// for bit (docs/design.md §2, §9).
TEST(PsdHessianPrior, ConfigKeyIsTheClampProjection) {
  const test::VioScenario scenario(10.0, 4.0);
  std::vector<Eigen::Vector3d> by_config, by_name;
  maxPositionError<float>(scenario, "sc-sc-sqp-f32", &by_config, true);
  maxPositionError<float>(scenario, "sc-sc-sqpc-f32", &by_name);
  EXPECT_EQ(by_config, by_name);
}

// The gauge-exact projection g (pivots below NumericTraits' relative floor set to zero; its
// nullspace against an SVD: test/linalg LdltGaugeExactFloorKeepsTheNullspace): the f32 Hessian
// storages and the f32 square root with it track the scenario, every stored Hessian prior
// positive semidefinite to the rounding of forming JᵀJ in float.
TEST(PsdGaugeExact, SinglePrecisionRunsHoldWithAPositiveSemidefinitePrior) {
  const test::VioScenario scenario(10.0, 12.0);
  const double bound = 30 * NumericTraits<float>::kEpsilon;
  for (const char* variant : {"sc-sc-sqg-f32", "sc-sc-sqpg-f32", "sc-sc-sqrtg-f32"}) {
    SCOPED_TRACE(variant);
    double min_eigen = 0;
    EXPECT_LT(maxPositionError<float>(scenario, variant, nullptr, false, &min_eigen), 0.05);
    EXPECT_GE(min_eigen, -bound);
  }
}

}  // namespace
}  // namespace marglab
