#include "core/frontend/frontend_options.h"

#include <cmath>

namespace marglab {

const char* toString(MotionPredictionSource source) {
  switch (source) {
    case MotionPredictionSource::kTracker:
      return "tracker";
    case MotionPredictionSource::kNone:
      return "none";
    case MotionPredictionSource::kEstimator:
      break;
  }
  return "estimator";
}

bool parseMotionPredictionSource(const std::string& text, MotionPredictionSource* source) {
  for (const MotionPredictionSource s :
       {MotionPredictionSource::kEstimator, MotionPredictionSource::kTracker,
        MotionPredictionSource::kNone}) {
    if (text == toString(s)) {
      *source = s;
      return true;
    }
  }
  return false;
}

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
