#pragma once
// One Levenberg–Marquardt linearization of a BAL problem, with the landmarks eliminated by the
// estimator's landmark blocks (core/linalg/landmark_block.h: LandmarkBlockNs = nullspace
// projection by QR, the square root kept; LandmarkBlockSc = Schur complement), in the phases of
// rootba's linearizors (Demmel et al., CVPR 2021, §4–5):
//
//   linearize(state)  every observation's residual and Jacobians (snavely_camera.h), weighted by
//                     the robust loss's √w; Jacobian scaling (Ceres', rootba's): every column of J
//                     is divided by ε + its norm (cameras over all their observations, each
//                     landmark over its own), so that the damping λI of the scaled problem is
//                     λ·diag(JᵀJ) of the original one up to ε; then each landmark's rows
//                     [J_p | J_l | r] (J_p over its cameras' 9 columns) go into its block: the
//                     in-place QR (ns) or the Hessian blocks (sc). A point seen only once (2 rows
//                     for 3 unknowns) cannot be eliminated; it stays fixed (counted).
//   solve(λ)          the landmark damping λI folded into each block, the reduced camera system
//                         (S + λI) δc = −g,   S = Σ_l (Q2ᵀJ_p)ᵀ(Q2ᵀJ_p)   (= H_pp − H_pl H_ll⁻¹
//                         H_lp)
//                     solved by Schur-Jacobi preconditioned CG (pcg.h; M = the 9×9 camera blocks
//                     of S + λI): matrix-free for ns, S x = Σ_l (Q2ᵀJ_p)ᵀ((Q2ᵀJ_p) x) over each
//                     landmark's reduced rows, never forming S; for sc, S is formed explicitly
//                     (dense: the reduced camera systems of the shipped problems are at most
//                     441 × 441); then the landmarks' back-substitution, the step unscaled, and the
//                     change of the undamped linearized cost ½‖J s + r‖² − ½‖r‖² (the LM gain
//                     ratio's denominator, from the blocks).
//
// Scalar is the block's: f32 solvers linearize, eliminate and iterate in float.

#include <memory>
#include <vector>

#include "core/ba/ba_state.h"
#include "core/ba/pcg.h"
#include "core/common/status.h"
#include "core/common/thread_pool.h"
#include "core/linalg/isa.h"

namespace marglab {

// Columns of one camera in the reduced camera system: ξ = (δt, δφ, δf, δk1, δk2).
constexpr int kBalCameraDim = 9;

template <typename Scalar>
struct BaStep {
  std::vector<Vec<Scalar, 9>> delta_cameras;  // ξ per camera (snavely_camera.h)
  std::vector<Vec3<Scalar>> delta_points;
  double model_change = 0;  // ½‖J s + r‖² − ½‖r‖² (undamped, robust-weighted)
  CgSummary cg;
};

// kNullspace: the projection kept implicit (LandmarkBlockNsImplicit, O(m) products per landmark);
// kNullspaceExplicit: the reduced rows Q2ᵀJ_p formed in place (LandmarkBlockNs, rootba's storage
// and the estimator's block, O(m²)); kSchur: LandmarkBlockSc.
enum class BaElimination { kNullspace, kNullspaceExplicit, kSchur };

// The linear system of one LM linearization (above). Made by makeBaLinearSystem: its code is
// compiled per ISA (landmark_system.cpp, with the landmark blocks it uses; core/isa_kernels.cmake)
// and the active ISA's copy is taken (core/linalg/isa.h); a system keeps the ISA it was made with.
template <typename Scalar>
class BaLinearSystem {
 public:
  virtual ~BaLinearSystem() = default;
  virtual Status linearize(const BalState<Scalar>& state, const RobustLoss& loss) = 0;
  virtual Status solve(Scalar lambda, const CgOptions& cg, BaStep<Scalar>* step) = 0;
  virtual int numFixedPoints() const = 0;
  // The reduced system S, g (scaled columns, landmarks damped as by the last solve) formed
  // densely: sc's explicit system; for ns the tests' check of the equivalence and of CG.
  virtual Status denseReducedSystem(MatX<Scalar>* S, VecX<Scalar>* g) const = 0;
};

// One ISA's entry point (core/estimator/linearization_kernels.h holds the table). Keeps a
// reference to the problem's observations (the problem must outlive the system).
template <typename Scalar>
struct BaKernels {
  std::unique_ptr<BaLinearSystem<Scalar>> (*make_system)(const BalProblem&, BaElimination,
                                                         ThreadPool&) = nullptr;
};
// Defined in landmark_system.cpp, compiled per ISA only.
template <typename Scalar>
BaKernels<Scalar> baKernelsIn();

// The system of the active ISA's copy, or of one ISA's (the tests compare the copies). It
// linearizes, multiplies and back-substitutes over the landmark blocks on the pool's threads
// (which must outlive it), with the same numbers for every thread count: the sums over landmarks
// are formed per camera in landmark order (ns: gradient, preconditioner, CG product) or in fixed
// chunks of landmarks added in chunk order (sc's reduced system).
template <typename Scalar>
std::unique_ptr<BaLinearSystem<Scalar>> makeBaLinearSystem(const BalProblem& problem,
                                                           BaElimination elimination,
                                                           ThreadPool& pool);
template <typename Scalar>
std::unique_ptr<BaLinearSystem<Scalar>> makeBaLinearSystem(const BalProblem& problem,
                                                           BaElimination elimination,
                                                           ThreadPool& pool, Isa isa);

}  // namespace marglab
