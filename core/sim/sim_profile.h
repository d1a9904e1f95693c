#pragma once
// The simulator's measurement profile (docs/design.md §5), config key `sim.profile`:
//   ideal      isotropic Gaussian pixel noise σ = 0.5 px, 1 % outliers displaced 5–20 px, no
//              drift, a track in every free grid cell (the defaults of TrackerOptions). It
//              isolates the numerics from the front-end and stays the default.
//   realistic  calibrated on real frames by tools/scripts/frontend_stats.py, one file per dataset
//              family (realisticProfilePath), because a front-end's noise, track life and stereo
//              share depend on the camera, the scene and the motion:
//                realistic_euroc.toml  EuRoC and TUM-VI runs; measured on the 74 real EuRoC
//                                      V1_01 frames inside the ground truth (static: the MAV
//                                      stands, so track loss is not measured there);
//                realistic_kitti.toml  KITTI runs; measured on the 51 real moving KITTI 06 frames
//                                      (datasets/kitti/06_images, 60 m of driving), with the right
//                                      camera's cx + 0.22 px so that the rectification's
//                                      disparity bias (results/real_kitti06) is not taken as
//                                      pixel noise (results/frontend_stats/README.md).
//   realistic-motion  the same model, calibrated on moving frames for every family (issue #40):
//                realistic_euroc_motion.toml  EuRoC and TUM-VI runs; measured on 100 real V1_01
//                                      stereo keyframes under motion (datasets/euroc/
//                                      V1_01_easy_keyframes), the track loss from KITTI 06;
//                realistic_kitti.toml  KITTI runs, as `realistic` (already moving frames).
//              A profile of its own, so that `realistic` keeps producing the committed results.
//              Each file holds:
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

#include "core/common/enum_names.h"
#include "core/data/types.h"
#include "core/sim/feature_tracker.h"

namespace marglab {

enum class SimProfile { kIdeal, kRealistic, kRealisticMotion };
inline constexpr EnumNames<SimProfile, 3> kSimProfileNames{
    {{SimProfile::kIdeal, "ideal"},
     {SimProfile::kRealistic, "realistic"},
     {SimProfile::kRealisticMotion, "realistic-motion"}}};
inline const char* toString(SimProfile value) { return nameOf(kSimProfileNames, value); }
inline bool parseSimProfile(const std::string& text, SimProfile* value) {
  return parseName(kSimProfileNames, text, value);
}

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

// The file of a non-ideal profile for a dataset family under datasetsRoot(): sim_profiles/
// realistic_kitti.toml for KITTI (both profiles), sim_profiles/realistic_euroc.toml (`realistic`)
// or realistic_euroc_motion.toml (`realistic-motion`) for EuRoC and TUM-VI (TUM-VI has no real
// frames of its own shipped; its indoor handheld stereo is closer to EuRoC's than to a car's).
std::string realisticProfilePath(DatasetKind kind, SimProfile profile = SimProfile::kRealistic);

// The tracker options of the realistic profile: the noise, drift, outlier and tracking fields from
// the file (the ideal profile is TrackerOptions as they are).
void applyRealisticProfile(const RealisticProfile& profile, TrackerOptions* options);

// Single simulator settings replaced on top of the profile, for one-factor studies (config keys
// sim.grid_cell_px, sim.loss_probability, sim.stereo_failure_probability; README "Where we
// depart", item 6): the grid decides the features per frame, the loss the track length, the
// stereo failure the stereo share, sim.facade_offset_scale (street worlds: KITTI) the depth of
// the facades beside the road (their lateral offsets, 5–12 m, times the scale). −1 (the
// default): the profile's or the dataset's value.
struct SimOverrides {
  double grid_cell_px = -1;
  double loss_probability = -1;
  double stereo_failure_probability = -1;
  double facade_offset_scale = -1;
  bool any() const {
    return grid_cell_px >= 0 || loss_probability >= 0 || stereo_failure_probability >= 0 ||
           facade_offset_scale >= 0;
  }
};

// The overrides that are set, written into the tracker and world options.
void applySimOverrides(const SimOverrides& overrides, TrackerOptions* options);
void applySimOverrides(const SimOverrides& overrides, WorldOptions* options);

}  // namespace marglab
