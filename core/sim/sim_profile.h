#pragma once
// The simulator's measurement profile (docs/design.md §5), config key `sim.profile`:
//   ideal      isotropic Gaussian pixel noise σ = 0.5 px, 1 % outliers displaced 5–20 px, no
//              drift, a track in every free grid cell (the defaults of TrackerOptions). It
//              isolates the numerics from the front-end and stays the default.
//   realistic  calibrated on real frames by tools/scripts/frontend_stats.py, which writes
//              datasets/sim_profiles/realistic_euroc.toml:
//                noise     per coordinate scale_px · t_ν (Student-t; heavier tails than a
//                          Gaussian), drawn as t_ν = z / √(g / (ν/2)), z ~ N(0, 1),
//                          g ~ Gamma(ν/2, 1) (Marsaglia–Tsang; shape < 1 by Gamma(a + 1) U^{1/a});
//                drift     each track's pixel offset d walks, d_{k+1} = d_k + step_px n_k,
//                          n_k ~ N(0, I₂), from d = 0 at detection; uv0 and uv1 share it (the
//                          right view is matched to the left's drifted patch);
//                outliers  wrong associations with the measured probability and displacement;
//                tracking  loss per frame, stereo failure, and the probability that a free grid
//                          cell yields a new track (real corners do not fill every cell).
//              The file's values are range-checked on reading; nothing of them is a constant here.

#include <string>

#include "core/sim/feature_tracker.h"

namespace marglab {

enum class SimProfile { kIdeal, kRealistic };
const char* toString(SimProfile profile);
// False for an unknown name.
bool parseSimProfile(const std::string& text, SimProfile* profile);

// The parameters of the realistic profile, as in its TOML file ([noise], [drift], [outliers],
// [tracking]; every key required, unknown keys are errors).
struct RealisticProfile {
  double nu = 0, scale_px = 0;     // [noise]
  double drift_step_px = 0;        // [drift] step_px
  double outlier_probability = 0;  // [outliers] probability
  double outlier_min_px = 0, outlier_max_px = 0;
  double loss_probability = 0;  // [tracking]
  double stereo_failure_probability = 0;
  double cell_fill_probability = 1;
};

// Throws InputError(path, line, what) for a missing file, syntax errors, unknown or missing keys
// and values outside their ranges (ν > 0, scales ≥ 0, probabilities in [0, 1], min ≤ max).
RealisticProfile readRealisticProfile(const std::string& path);

// datasets/sim_profiles/realistic_euroc.toml under datasetsRoot().
std::string defaultRealisticProfilePath();

// The tracker options of the realistic profile: the noise, drift, outlier and tracking fields from
// the file (the ideal profile is TrackerOptions as they are).
void applyRealisticProfile(const RealisticProfile& profile, TrackerOptions* options);

}  // namespace marglab
