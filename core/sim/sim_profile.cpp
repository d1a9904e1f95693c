#include "core/sim/sim_profile.h"

#include <fmt/core.h>

#include <toml++/toml.h>
#include <cmath>
#include <filesystem>
#include <functional>
#include <set>
#include <vector>

#include "core/common/error.h"
#include "core/data/sequence.h"

namespace marglab {
namespace {

// One key of the profile file: where its value goes and its range [lo, hi] (lo_open: lo < v).
struct ProfileKey {
  const char* section;
  const char* key;
  double* value;
  double lo, hi;
  bool lo_open;
};

std::vector<ProfileKey> profileKeys(RealisticProfile& p) {
  constexpr double kInf = INFINITY;
  return {{"noise", "nu", &p.nu, 0, 1e6, true},
          {"noise", "scale_px", &p.scale_px, 0, 100, false},
          {"drift", "step_px", &p.drift_step_px, 0, 100, false},
          {"outliers", "probability", &p.outlier_probability, 0, 1, false},
          {"outliers", "min_px", &p.outlier_min_px, 0, kInf, false},
          {"outliers", "max_px", &p.outlier_max_px, 0, kInf, false},
          {"tracking", "loss_probability", &p.loss_probability, 0, 1, false},
          {"tracking", "stereo_failure_probability", &p.stereo_failure_probability, 0, 1, false},
          {"tracking", "cell_fill_probability", &p.cell_fill_probability, 0, 1, true}};
}

int lineOf(const toml::node& node) { return static_cast<int>(node.source().begin.line); }

// Unknown sections and keys are errors (a typo must not silently keep a default).
void checkKnownKeys(const toml::table& root, const std::vector<ProfileKey>& keys,
                    const std::string& path) {
  for (const auto& [section, node] : root) {
    const toml::table* table = node.as_table();
    if (table == nullptr) throw InputError(path, lineOf(node), "expected a table [section]");
    for (const auto& [key, value] : *table) {
      bool known = false;
      for (const ProfileKey& k : keys) known |= section.str() == k.section && key.str() == k.key;
      if (!known) {
        throw InputError(
            path, lineOf(value),
            fmt::format("unknown key {}.{} in a simulator profile", section.str(), key.str()));
      }
    }
  }
}

void readKey(const toml::table& root, const ProfileKey& k, const std::string& path) {
  const toml::node* node = root.at_path(std::string(k.section) + "." + k.key).node();
  if (node == nullptr) throw InputError(path, 0, fmt::format("missing {}.{}", k.section, k.key));
  const std::optional<double> v = node->value<double>();
  const bool ok = v && std::isfinite(*v) && (k.lo_open ? *v > k.lo : *v >= k.lo) && *v <= k.hi;
  if (!ok) {
    throw InputError(path, lineOf(*node),
                     fmt::format("{}.{}: expected a number in {}{}, {}]", k.section, k.key,
                                 k.lo_open ? "(" : "[", k.lo, k.hi));
  }
  *k.value = *v;
}

}  // namespace

RealisticProfile readRealisticProfile(const std::string& path) {
  toml::table root;
  try {
    root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    if (!std::filesystem::exists(path)) throw InputError(path, 0, "cannot open the profile file");
    throw InputError(path, static_cast<int>(e.source().begin.line), std::string(e.description()));
  }
  RealisticProfile profile;
  const std::vector<ProfileKey> keys = profileKeys(profile);
  checkKnownKeys(root, keys, path);
  for (const ProfileKey& k : keys) readKey(root, k, path);
  if (profile.outlier_min_px > profile.outlier_max_px) {
    throw InputError(path, 0,
                     fmt::format("outliers.min_px = {} > outliers.max_px = {}: expected min <= max",
                                 profile.outlier_min_px, profile.outlier_max_px));
  }
  return profile;
}

std::string realisticProfilePath(DatasetKind kind, SimProfile profile) {
  const char* euroc = profile == SimProfile::kRealisticMotion ? "realistic_euroc_motion.toml"
                                                              : "realistic_euroc.toml";
  const char* file = kind == DatasetKind::kKitti ? "realistic_kitti.toml" : euroc;
  return (std::filesystem::path(datasetsRoot()) / "sim_profiles" / file).string();
}

void applyRealisticProfile(const RealisticProfile& profile, TrackerOptions* options) {
  options->student_nu = profile.nu;
  options->pixel_sigma = profile.scale_px;
  options->drift_step_px = profile.drift_step_px;
  options->outlier_probability = profile.outlier_probability;
  options->outlier_min_px = profile.outlier_min_px;
  options->outlier_max_px = profile.outlier_max_px;
  options->loss_probability = profile.loss_probability;
  options->stereo_failure_probability = profile.stereo_failure_probability;
  options->cell_fill_probability = profile.cell_fill_probability;
}

void applySimOverrides(const SimOverrides& overrides, TrackerOptions* options) {
  if (overrides.grid_cell_px >= 0) options->grid_cell_px = overrides.grid_cell_px;
  if (overrides.loss_probability >= 0) options->loss_probability = overrides.loss_probability;
  if (overrides.stereo_failure_probability >= 0) {
    options->stereo_failure_probability = overrides.stereo_failure_probability;
  }
}

void applySimOverrides(const SimOverrides& overrides, WorldOptions* options) {
  if (overrides.facade_offset_scale < 0) return;
  options->facade_offset_min *= overrides.facade_offset_scale;
  options->facade_offset_max *= overrides.facade_offset_scale;
}

}  // namespace marglab
