// The per-ISA kernels (core/linalg/isa.h, core/estimator/linearization_kernels.h): the ISA names
// and the CPU check, and on the shipped captured windows the damped LM step of every ISA the CPU
// has solves the reduced system formed by the SSE2 code to the backward error of the scalar type,
// and is the same bit for bit when computed twice.

#include <gtest/gtest.h>

#include <limits>

#include "core/bench/perf_suite.h"
#include "core/common/error.h"
#include "core/estimator/linearization_kernels.h"

namespace marglab {
namespace {

TEST(Isa, NamesResolveToTheIsaOrAnError) {
  EXPECT_TRUE(cpuSupports(Isa::kSse2));
  EXPECT_EQ(resolveIsa("auto"), bestIsa());
  EXPECT_TRUE(isaAvailable(bestIsa()));
  for (const Isa isa : kAllIsas) {
    if (isaAvailable(isa)) {
      EXPECT_EQ(resolveIsa(isaName(isa)), isa);
      EXPECT_EQ(kernelsOf(isa).isa, isa);  // each ISA's table is its own
    } else {
      EXPECT_THROW(resolveIsa(isaName(isa)), InputError);
    }
  }
  EXPECT_THROW(resolveIsa("avx"), UsageError);
  EXPECT_THROW(resolveIsa(""), UsageError);
}

// Restores the process's ISA after a test that forces one.
class IsaScope {
 public:
  explicit IsaScope(Isa isa) : saved_(activeIsa()) { setActiveIsa(isa); }
  ~IsaScope() { setActiveIsa(saved_); }

 private:
  Isa saved_;
};

template <typename Scalar>
struct System {
  MatX<Scalar> H;  // undamped reduced system
  VecX<Scalar> b;
  VecX<Scalar> delta;  // damped step
};

template <typename Scalar>
System<Scalar> dampedStep(Isa isa, const WindowSnapshot& w, const char* variant, Scalar lambda) {
  const IsaScope scope(isa);
  const auto est = SlidingWindowEstimator<Scalar>::fromSnapshot(w, Variant::parse(variant));
  typename Linearization<Scalar>::Options options;
  options.lambda_min = static_cast<Scalar>(w.config.lambda_min);
  const auto lin = makeLinearization<Scalar>(Variant::parse(variant), options);
  lin->linearize(est.window());
  EXPECT_TRUE(lin->eliminate().ok());
  LinearStep<Scalar> step;
  EXPECT_TRUE(lin->solve(lambda, &step).ok());
  return {lin->reducedHessian(), lin->reducedGradient(), step.delta};
}

// ‖(H + D) δ + b‖ / (‖H + D‖ ‖δ‖ + ‖b‖) with the LM damping D of solveDampedLdlt.
template <typename Scalar>
double backwardError(System<Scalar> s, const VecX<Scalar>& delta, Scalar lambda,
                     Scalar lambda_min) {
  for (Eigen::Index i = 0; i < s.H.rows(); ++i) {
    s.H(i, i) += std::max(lambda * s.H(i, i), lambda_min);
  }
  const MatXd H = s.H.template cast<double>();
  const VecXd b = s.b.template cast<double>(), d = delta.template cast<double>();
  return (H * d + b).norm() / (H.norm() * d.norm() + b.norm());
}

// Both eliminations are backward stable: each ISA's reduced system differs from the SSE2 one by
// O(ε ‖H‖) times a small multiple of the rows per landmark, and the LDLT solve adds O(ε), so its
// step solves the SSE2 system to a backward error of c ε whatever κ(H) (the same bound as
// test_vo's mixed-precision step).
template <typename Scalar>
void checkEveryIsa(const char* variant) {
  const Scalar lambda = Scalar(1e-4);
  const double eps = std::numeric_limits<Scalar>::epsilon();
  for (const NamedWindow& nw : loadWindows()) {
    SCOPED_TRACE(nw.name + " " + variant);
    const Scalar lambda_min = static_cast<Scalar>(nw.window.config.lambda_min);
    const System<Scalar> ref = dampedStep<Scalar>(Isa::kSse2, nw.window, variant, lambda);
    ASSERT_GT(ref.delta.norm(), 0);
    for (const Isa isa : kAllIsas) {
      if (!isaAvailable(isa)) continue;
      SCOPED_TRACE(isaName(isa));
      const System<Scalar> s = dampedStep<Scalar>(isa, nw.window, variant, lambda);
      EXPECT_LT(backwardError(ref, s.delta, lambda, lambda_min), 100 * eps);
      const System<Scalar> again = dampedStep<Scalar>(isa, nw.window, variant, lambda);
      EXPECT_TRUE(again.delta == s.delta) << "not reproducible";
    }
  }
}

TEST(IsaKernels, NullspaceStepOfEveryIsaSolvesTheSse2SystemF64) {
  checkEveryIsa<double>("ns-qr-sqrt-f64");
}
TEST(IsaKernels, SchurStepOfEveryIsaSolvesTheSse2SystemF64) {
  checkEveryIsa<double>("sc-sc-sq-f64");
}
TEST(IsaKernels, NullspaceStepOfEveryIsaSolvesTheSse2SystemF32) {
  checkEveryIsa<float>("ns-qr-sqrt-f32");
}

}  // namespace
}  // namespace marglab
