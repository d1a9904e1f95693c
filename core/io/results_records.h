#pragma once
// The rows of the results file's tables /frames, /marg, /sparsify and /frontend (docs/design.md
// §6). These structs are the schema's only source: each member is one column through one line of
// its table in core/io/results_schema.cpp, which gives its name, unit, stored type and shape.
//
// Whoever produces a row reports in its record type, so no code copies a row field by field (a
// forgotten line of such a copy would write the member's default silently): the estimator's
// FrameResult and SparsifyEvent (core/estimator) and the front-end's FrontendFrameStats
// (core/frontend) derive from FrameRecord, SparsifyRecord and FrontendRecord and add only what the
// file does not store; makeMargRecord (results_file.h) fills a MargRecord from the diagnostics.
//
// Kept free of HDF5 so that those producers can include it.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <limits>

#include "core/common/eigen_types.h"
#include "core/diagnostics/gauge.h"

namespace marglab {

// One row of /frames. The estimator fills it (FrameResult); p_gt comes from the run's ground
// truth.
struct FrameRecord {
  std::int64_t t_ns = 0;
  bool is_keyframe = false;
  int n_landmarks = 0;
  int n_observations = 0;
  int lm_iterations = 0;
  // The tracking monitor's inputs (core/pipeline/tracking_monitor.h); 0 in older files. The
  // frame's observations of landmarks already in the window; after the optimization, the
  // observations Window::frameReprojectionErrors checks, and those of them farther than
  // failure.inconsistent_px from their landmark's projection.
  int n_connected = 0;
  int n_checked = 0;
  int n_inconsistent = 0;
  double cost_initial = 0.0;
  double cost_final = 0.0;
  double t_opt_s = 0.0;
  double t_marg_s = 0.0;
  // The right camera's cx offset after this frame's optimization ([estimator]
  // estimate_right_cx_offset); NaN when it is not estimated, and in older files.
  double right_cx_offset_px = std::numeric_limits<double>::quiet_NaN();
  Eigen::Vector3d p_est = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_est = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_gt = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  // Written by finish() (the alignment needs every frame); appendFrame ignores it.
  double ate_error = std::numeric_limits<double>::quiet_NaN();
};

// One row of /marg: the gauge diagnostics of one marginalization event (makeMargRecord).
struct MargRecord {
  std::int64_t frame_index = 0;
  std::int64_t t_ns = 0;
  int prior_cols = 0;
  int prior_rows = 0;
  int rank = 0;
  int n_negative = 0;
  double sigma_min = 0.0;
  double sigma_max = 0.0;
  double eig_tolerance = 0.0;
  Vec7d dEm = Vec7d::Zero();
  VecXd eigenvalues;  // ascending, size prior_cols
};

// One keyframe marginalization of a dense / nfr run (/sparsify). The estimator fills it
// (SparsifyEvent) but frame_index and t_ns, which locate it in /frames.
struct SparsifyRecord {
  std::int64_t frame_index = 0;
  std::int64_t t_ns = 0;
  int blanket_cols = 0;
  int n_blanket_poses = 0;
  int n_blanket_landmarks = 0;
  std::int64_t nnz_dense = 0;
  std::int64_t nnz_sparse = 0;
  // εᵀΛε of the dense prior and of what replaced it along the gauge directions (columns
  // kGaugeDirectionNames); NaN in files written before these columns existed.
  Vec7d info_dense = Vec7d::Constant(std::numeric_limits<double>::quiet_NaN());
  Vec7d info_sparse = Vec7d::Constant(std::numeric_limits<double>::quiet_NaN());
  double kld = std::numeric_limits<double>::quiet_NaN();
  bool recovered = false;
  double t_schur_s = 0.0;
  double t_recovery_s = 0.0;
  double t_insert_s = 0.0;
};

// One row of /frontend, per frame the track source produced (FrontendFrameStats).
struct FrontendRecord {
  std::int64_t t_ns = 0;
  int n_features = 0;
  int n_tracked = 0;
  int n_new = 0;
  int n_stereo = 0;
  double t_frontend_s = std::numeric_limits<double>::quiet_NaN();
};

}  // namespace marglab
