#include "core/ba/ba_state.h"

#include <cmath>

#include "core/common/scalar.h"

namespace marglab {

template <typename Scalar>
BalState<Scalar> BalState<Scalar>::fromProblem(const BalProblem& problem) {
  BalState state;
  state.cameras.reserve(problem.cameras.size());
  for (const Vec<double, 9>& c : problem.cameras) {
    state.cameras.push_back(SnavelyCamera<Scalar>::fromBal(c));
  }
  state.points.reserve(problem.points.size());
  for (const Vec3<double>& X : problem.points) state.points.push_back(X.cast<Scalar>());
  return state;
}

template <typename Scalar>
void BalState<Scalar>::writeTo(BalProblem* problem) const {
  for (size_t i = 0; i < cameras.size(); ++i) problem->cameras[i] = cameras[i].toBal();
  for (size_t i = 0; i < points.size(); ++i) problem->points[i] = points[i].template cast<double>();
}

template <typename Scalar>
std::pair<Scalar, Scalar> RobustLoss::costAndSqrtWeight(Scalar s) const {
  const Scalar delta = Scalar(huber_px);
  if (huber_px <= 0 || s < delta * delta) return {Scalar(0.5) * s, Scalar(1)};
  const Scalar w = delta / std::sqrt(s);
  return {Scalar(0.5) * (Scalar(2) - w) * w * s, std::sqrt(w)};
}

template <typename Scalar>
CostSummary evaluateCost(const std::vector<BalObservation>& observations,
                         const BalState<Scalar>& state, const RobustLoss& loss) {
  CostSummary summary;
  for (const BalObservation& obs : observations) {
    Vec<Scalar, 2> r;
    const bool in_front = snavelyResidual<Scalar>(
        state.cameras[obs.camera], state.points[obs.point], obs.z.cast<Scalar>(), &r);
    if (!in_front) ++summary.num_behind;
    if (!r.allFinite()) summary.finite = false;
    summary.cost += double(loss.costAndSqrtWeight(r.squaredNorm()).first);
  }
  return summary;
}

#define MARGLAB_INST(S)                                                                        \
  template struct BalState<S>;                                                                 \
  template std::pair<S, S> RobustLoss::costAndSqrtWeight<S>(S) const;                          \
  template CostSummary evaluateCost<S>(const std::vector<BalObservation>&, const BalState<S>&, \
                                       const RobustLoss&);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
