#pragma once
// The variables of a BAL problem in a solver's precision, and the cost ½ Σ ρ(‖r‖²) over all
// observations (Ceres' and rootba's definition, so that costs compare across solvers).
//
// Robust loss (rootba's Huber, bal_bundle_adjustment_helper.cpp): with threshold δ > 0 pixels and
// s = ‖r‖², the weight w = 1 for √s < δ, else δ/√s, and the cost of one residual
//     ½ ρ(s) = ½ (2 − w) w s      (= ½ s inside, δ√s − ½δ² outside: Huber's function).
// The linearization weighs the residual and its Jacobian by √w (iteratively reweighted least
// squares; rootba's choice; Ceres' Corrector differs by a second-order term outside δ).

#include <vector>

#include "core/ba/bal_problem.h"
#include "core/ba/snavely_camera.h"

namespace marglab {

template <typename Scalar>
struct BalState {
  std::vector<SnavelyCamera<Scalar>> cameras;
  std::vector<Vec3<Scalar>> points;

  static BalState fromProblem(const BalProblem& problem);
  // Cameras (ω, t, f, k1, k2) and points back into `problem`'s layout.
  void writeTo(BalProblem* problem) const;
};

// No loss: huber_px = 0.
struct RobustLoss {
  double huber_px = 0;
  // (½ ρ(s), √w) of one residual with s = ‖r‖².
  template <typename Scalar>
  std::pair<Scalar, Scalar> costAndSqrtWeight(Scalar s) const;
};

struct CostSummary {
  double cost = 0;     // ½ Σ ρ(‖r‖²), accumulated in double
  int num_behind = 0;  // observations whose point is behind its camera (P_z ≥ 0)
  bool finite = true;  // every residual finite
};

template <typename Scalar>
CostSummary evaluateCost(const std::vector<BalObservation>& observations,
                         const BalState<Scalar>& state, const RobustLoss& loss);

}  // namespace marglab
