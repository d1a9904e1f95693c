#pragma once
// All per-marginalization diagnostics of docs/design.md §4 in one call: the spectrum of H_m
// (prior_analysis.h) and ΔE_m along the 7 gauge test directions (gauge.h, eq. 27), in double.
// The estimator converts its prior to double first: squared storage passes (H_m, b_m) as stored,
// square-root storage passes (J_m, r_m) and H_m = J_mᵀJ_m, b_m = J_mᵀr_m are formed here.
//
// Seed of the random direction: pass the run's diagnostics seed plus the marginalization event
// index, so that every variant of a sequence probes its k-th prior along the same direction
// whenever the layouts have the same size.

#include <cstdint>

#include "core/diagnostics/gauge.h"
#include "core/diagnostics/prior_analysis.h"

namespace marglab {

struct PriorDiagnostics {
  PriorSpectrum spectrum;
  Vec7d dEm;  // in kGaugeDirectionNames order
};

PriorDiagnostics diagnosePrior(const MatXd& H_m, const VecXd& b_m, const PriorLayout& layout,
                               const GaugeState& state, std::uint64_t seed);
PriorDiagnostics diagnoseSqrtPrior(const MatXd& J_m, const VecXd& r_m, const PriorLayout& layout,
                                   const GaugeState& state, std::uint64_t seed);

}  // namespace marglab
