// The ISA copies of the BA linear system (core/ba/landmark_system.cpp, compiled per ISA through
// core/isa_kernels.cmake) agree with each other to rounding: the same linearization, reduced
// system and step, in both precisions, on a small problem. They differ only in the order of the
// sums (vector width) and FMA contraction, so the tolerances are a few ε of the scalar: for the
// reduced system, the error of forming a sum of products of (2n)-row blocks — γ_{2n} ≈ 2n ε
// relative to ‖S‖ (n ≤ 3 views per point here), and the QR's backward error for ns, c·n ε
// (Higham, Thm. 19.4); for the step, that times the condition number κ of the damped reduced
// system (computed here), as for any backward-stable solve.
#include <fmt/core.h>
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include "core/ba/landmark_system.h"
#include "core/common/scalar.h"
#include "core/common/source_dir.h"

namespace marglab {
namespace {

template <typename Scalar>
struct Solved {
  MatX<double> S;
  VecX<double> g, step;
  double model_change = 0;
};

template <typename Scalar>
Solved<Scalar> solveOnce(const BalProblem& problem, BaElimination elimination, Isa isa,
                         Scalar lambda) {
  ThreadPool pool(1);
  const auto system = makeBaLinearSystem<Scalar>(problem, elimination, pool, isa);
  const BalState<Scalar> state = BalState<Scalar>::fromProblem(problem);
  EXPECT_TRUE(system->linearize(state, RobustLoss{1.0}).ok());
  BaStep<Scalar> step;
  // One CG iteration: x = α M⁻¹(−g). With more, the ISAs may stop CG at different iterations
  // (its forcing rule compares the decrease of the quadratic with η), and the steps then differ
  // by the truncation, not by rounding.
  EXPECT_TRUE(system->solve(lambda, CgOptions{1, 0.1}, &step).ok());
  MatX<Scalar> S;
  VecX<Scalar> g;
  EXPECT_TRUE(system->denseReducedSystem(&S, &g).ok());
  Solved<Scalar> out{S.template cast<double>(), g.template cast<double>(), {}, step.model_change};
  out.step.resize(9 * step.delta_cameras.size() + 3 * step.delta_points.size());
  Eigen::Index k = 0;
  for (const auto& c : step.delta_cameras)
    out.step.template segment<9>(std::exchange(k, k + 9)) = c.template cast<double>();
  for (const auto& p : step.delta_points)
    out.step.template segment<3>(std::exchange(k, k + 3)) = p.template cast<double>();
  return out;
}

template <typename Scalar>
void expectIsasAgree(BaElimination elimination) {
  const BalProblem problem =
      loadBalProblem(std::string(sourceDir()) + "/datasets/bal/dubrovnik-3-7-pre.txt");
  const Scalar lambda = Scalar(1e-4);
  const Solved<Scalar> reference = solveOnce<Scalar>(problem, elimination, Isa::kSse2, lambda);
  const double eps = NumericTraits<Scalar>::kEpsilon;
  const int max_track = 3;
  const double system_tol = 10.0 * (2 * max_track) * eps;
  // The preconditioner's 9×9 camera blocks of S + λI are solved by Cholesky: their largest
  // condition number amplifies the rounding of S into the step.
  double kappa = 1;
  for (Eigen::Index c = 0; c < reference.S.rows(); c += 9) {
    const MatX<double> block =
        reference.S.block(c, c, 9, 9) + double(lambda) * MatX<double>::Identity(9, 9);
    const auto spectrum = Eigen::SelfAdjointEigenSolver<MatX<double>>(block).eigenvalues();
    kappa = std::max(kappa, spectrum.maxCoeff() / spectrum.minCoeff());
  }
  // Componentwise bounds of sums of products (Higham §3.5): S = Σ A_lᵀA_l and g = Σ A_lᵀb_l with
  // A_l = Q2ᵀJ_p (ns) or the Schur complement's factors (sc) err by at most γ |A|ᵀ|A| and
  // γ |A|ᵀ|b|, whose norms are at most γ trace(S) and γ √trace(S) ‖b‖, with ‖b‖² ≤ ‖√w r‖² ≤ 2·cost.
  const double cost =
      evaluateCost(problem.observations, BalState<Scalar>::fromProblem(problem), RobustLoss{1.0})
          .cost;
  const double S_scale = reference.S.trace();
  const double g_scale = std::sqrt(S_scale * 2 * cost);
  for (const Isa isa : availableIsas()) {
    const Solved<Scalar> other = solveOnce<Scalar>(problem, elimination, isa, lambda);
    const double S_error = (other.S - reference.S).norm() / S_scale;
    const double g_error = (other.g - reference.g).norm() / g_scale;
    const double step_error = (other.step - reference.step).norm() / reference.step.norm();
    testing::Test::RecordProperty(
        fmt::format("{}_{}_{}_step_error", isaName(isa), NumericTraits<Scalar>::name(),
                    elimination == BaElimination::kNullspace           ? "ns"
                    : elimination == BaElimination::kNullspaceExplicit ? "nsx"
                                                                       : "sc"),
        fmt::format("{:.3e} (kappa {:.2e})", step_error, kappa));
    EXPECT_LE(S_error, system_tol) << isaName(isa);
    EXPECT_LE(g_error, system_tol) << isaName(isa);
    EXPECT_LE(step_error, system_tol * kappa) << isaName(isa) << " κ " << kappa;
    EXPECT_NEAR(other.model_change / reference.model_change, 1.0, system_tol * kappa)
        << isaName(isa);
  }
}

TEST(BaIsa, CopiesAgreeToRoundingNullspaceF64) {
  expectIsasAgree<double>(BaElimination::kNullspace);
}
TEST(BaIsa, CopiesAgreeToRoundingNullspaceExplicitF64) {
  expectIsasAgree<double>(BaElimination::kNullspaceExplicit);
}
TEST(BaIsa, CopiesAgreeToRoundingSchurF64) { expectIsasAgree<double>(BaElimination::kSchur); }
#if defined(MARGLAB_WITH_FLOAT)
TEST(BaIsa, CopiesAgreeToRoundingNullspaceF32) {
  expectIsasAgree<float>(BaElimination::kNullspace);
}
TEST(BaIsa, CopiesAgreeToRoundingNullspaceExplicitF32) {
  expectIsasAgree<float>(BaElimination::kNullspaceExplicit);
}
TEST(BaIsa, CopiesAgreeToRoundingSchurF32) { expectIsasAgree<float>(BaElimination::kSchur); }
#endif

}  // namespace
}  // namespace marglab
