#include "core/frontend/frontend_options.h"

#include <cmath>

namespace marglab {

FrontendOptions resolveFrontendOptions(const FrontendOptions& options, DatasetKind kind) {
  FrontendOptions out = options;
  const bool kitti = kind == DatasetKind::kKitti;
  if (out.grid_cell_px < 0) {
    out.grid_cell_px = static_cast<int>(std::lround(datasetDefaults(kind).grid_cell_px));
  }
  if (out.pyramid_levels < 0) out.pyramid_levels = kitti ? 4 : 3;
  if (out.detect_margin_px < 0) out.detect_margin_px = kitti ? 150 : 0;
  if (out.disparity_guesses_px.empty()) {
    out.disparity_guesses_px = kitti ? std::vector<double>{0, 10, 25, 45, 70}
                                     : std::vector<double>{0, 12, 30, 55, 85, 120};
  }
  return out;
}

}  // namespace marglab
