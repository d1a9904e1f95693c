#pragma once
// One Levenberg–Marquardt linearization of the window, in the phases every optimization method
// shares (after Basalt's LinearizationAbsQR / LinearizationAbsSC):
//
//   linearize(window)  the landmarks' reprojection rows [J_p | J_l | r] (per landmark, in the
//                      pool's chunks), the IMU factors, the rows taken as they are (landmarks of a
//                      dense prior, recovered unary factors) and the prior; the last three form the
//                      fixed part of the reduced camera system H_fixed, b_fixed;
//   eliminate()        each landmark block is set up for elimination (ns: in-place Householder QR;
//                      sc: its Hessian blocks). Without landmark damping (the paper's setting) the
//                      reduced system does not depend on λ: the landmarks are added to H_fixed here,
//                      once per linearization; a landmark that cannot be eliminated then stays fixed
//                      in this iteration;
//   solve(λ)           the reduced system with the landmarks damped for λ (when landmark damping is
//                      on), its damped LDLT solve H_ii += max(λ H_ii, λ_min) (preconditioned for
//                      the storages sqp / sqj: core/linalg/rcs_solve.h), the landmarks'
//                      back-substitution, and the change of the undamped linearized energy along
//                      the step (the LM gain ratio's denominator).
//
// The landmark elimination is the method: LandmarkLinearization<Scalar, Block> takes the landmark
// block type (core/linalg/landmark_block.h: LandmarkBlockNs = nullspace projection, LandmarkBlockSc =
// Schur complement), whose scalar may be lower than the system's — `mixed` eliminates the landmarks
// in float and keeps the reduced system, the prior and the marginalization in double: the
// Jacobians are cast to float per landmark, the reduced rows' Gram matrix is formed in float and
// accumulated in double, the step is cast to float once per solve.
//
// The estimator's optimizer (levenberg_marquardt.h), the equivalence tests and `marglab bench`
// (core/bench) all run these objects.

#include <memory>
#include <set>
#include <vector>

#include "core/common/status.h"
#include "core/estimator/variant.h"
#include "core/estimator/window.h"
#include "core/linalg/preconditioner.h"

namespace marglab {

// The step of one solve: the reduced-system variables (window column order) and each eliminated
// landmark's increment (in landmarks() order; zero for a landmark that stayed fixed).
template <typename Scalar>
struct LinearStep {
  VecX<Scalar> delta;
  std::vector<Vec3<Scalar>> delta_l;
  Scalar model_change = 0;  // ½‖J s + r‖² − ½‖r‖² of the undamped linearized energy
};

template <typename Scalar>
class Linearization {
 public:
  struct Options {
    bool damp_landmarks = false;  // LM damping on the landmarks too (not the paper's setting)
    Scalar lambda_min = 0;
    // Of the damped reduced system before its LDLT (storages sqp / sqj).
    Preconditioning preconditioning = Preconditioning::kNone;
    // A damped reduced system that is not positive definite is solved all the same
    // (lm.indefinite_system = "solve", core/linalg/rcs_solve.h).
    bool solve_indefinite = false;
  };
  virtual ~Linearization() = default;

  virtual void linearize(const Window<Scalar>& window) = 0;
  virtual Status eliminate() = 0;
  virtual Status solve(Scalar lambda, LinearStep<Scalar>* step) = 0;

  // After linearize(): the system's columns and the eliminated landmarks' Jacobians.
  virtual const ColumnMap& columns() const = 0;
  virtual int numColumns() const = 0;
  virtual const std::vector<LandmarkJacobians<Scalar>>& landmarks() const = 0;
  // After eliminate(): the reduced system (λ-independent part).
  virtual const MatX<Scalar>& reducedHessian() const = 0;
  virtual const VecX<Scalar>& reducedGradient() const = 0;
};

// The linearization of a variant's landmark elimination (ns | sc, and mixed precision for ns).
template <typename Scalar>
std::unique_ptr<Linearization<Scalar>> makeLinearization(
    const Variant& variant, const typename Linearization<Scalar>::Options& options);
// The same for an elimination method alone (in the system's precision).
template <typename Scalar>
std::unique_ptr<Linearization<Scalar>> makeLinearization(
    OptElimination elimination, const typename Linearization<Scalar>::Options& options);

}  // namespace marglab
