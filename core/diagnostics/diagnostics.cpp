#include "core/diagnostics/diagnostics.h"

namespace marglab {

PriorDiagnostics diagnosePrior(const MatXd& H_m, const VecXd& b_m, const PriorLayout& layout,
                               const GaugeState& state, std::uint64_t seed) {
  PriorDiagnostics d;
  d.spectrum = analyzePrior(H_m);
  d.dEm =
      priorCostChange(H_m, b_m, gaugeDirections(layout, static_cast<int>(H_m.cols()), state, seed));
  return d;
}

PriorDiagnostics diagnoseSqrtPrior(const MatXd& J_m, const VecXd& r_m, const PriorLayout& layout,
                                   const GaugeState& state, std::uint64_t seed) {
  return diagnosePrior(hessianFromSqrt(J_m), gradientFromSqrt(J_m, r_m), layout, state, seed);
}

}  // namespace marglab
