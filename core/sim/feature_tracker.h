#pragma once
// Simulated stereo feature tracking on a grid, like a KLT front-end (docs/design.md §5).
//
// Cameras. At each cam0 timestamp t inside the trajectory span, with T_w_b(t) from the
//   trajectory and the extrinsics T_b_c of the calibration (KITTI: body = cam0):
//     R_w_c = R_w_b R_b_c,  p_w_c = R_w_b t_b_c + p_w_b,  p_c = R_w_cᵀ (p_w − p_w_c),
//     (u, v) = (fx x/z + cx, fy y/z + cy)
//   i.e. measurements are in the UNDISTORTED pinhole image of the calibration's fx, fy, cx, cy
//   (distortion coefficients are ignored); pixel centres at integer coordinates (camera.h).
// Visibility in a camera: min_depth ≤ z ≤ max_depth, border ≤ u ≤ width−1−border (same for v),
//   the point's surface faces the camera (back-face culling, World::facing) and, in cam0, no
//   world wall (World::walls) lies in front of it. Walls are tested in a per-image-column depth
//   buffer in the camera's x–z plane (walls taken as vertical, as for KITTI's level cameras);
//   a stereo match needs cam1 visibility without the wall test (baseline ≪ wall distances).
// Per frame, in this order (every random draw in a fixed order, so a seed fixes the stream):
//   1. Continue: each active track whose landmark is still visible in cam0 survives with
//      probability 1 − loss_probability, and is measured (below). Others end.
//   2. Detect: the image is divided into cells of grid_cell_px (cell (i, j) covers
//      [i c, (i+1) c) × [j c, (j+1) c), the last row/column partial). A cell is occupied when a
//      continued track's measured uv0 lies in it. In each free cell one new track starts, on a
//      visible landmark that is not tracked now and projects into the cell: the one closest to
//      the cell centre (kClosestToCellCentre, the default, as a corner detector's strongest
//      response is a fixed property of the point) or a pseudo-random one (kRandom, a hash of
//      landmark, frame and seed). A landmark whose track ended may be re-detected: new track id.
//   3. Measure: uv0 = π(p_c0) + σ n0, and if the landmark is visible in cam1 and the stereo match
//      does not fail (probability stereo_failure_probability): has_right, uv1 = π(p_c1) + σ n1
//      (n0, n1 independent standard normal 2-vectors). With probability outlier_probability the
//      observation is an outlier (is_outlier = true): uv0, and uv1 if matched, are displaced in
//      independent uniformly random directions by a distance uniform in
//      [outlier_min_px, outlier_max_px], then clamped to the image.
//   With noise = false and outliers = false the measurements are exact projections.
//   The realistic profile (sim_profile.h) adds, each drawn only when enabled (so that the ideal
//   stream is unchanged): Student-t pixel noise (student_nu > 0: σ t_ν instead of σ n); a drift
//   of each continued track, d += drift_step_px (n_u, n_v) after its loss draw and before it is
//   measured (d = 0 at detection; uv0 and uv1 both get + d, before outliers); and in step 2 a
//   Bernoulli(cell_fill_probability) per free cell that has a candidate, in cell order.
// Track ids count from 0 in order of detection; landmark_id indexes TrackStream::landmarks_w
// (= World::points_w).

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/data/tracks.h"
#include "core/data/types.h"
#include "core/sim/trajectory_spline.h"
#include "core/sim/world.h"

namespace marglab {

enum class DetectionPolicy { kClosestToCellCentre, kRandom };

struct TrackerOptions {
  double grid_cell_px = 50.0;  // DatasetDefaults::grid_cell_px
  double border_px = 3.0;
  double min_depth = 0.2;                    // [m]
  double max_depth = 40.0;                   // [m]
  double loss_probability = 0.03;            // per frame and track
  double stereo_failure_probability = 0.03;  // per observation
  bool noise = true;
  double pixel_sigma = 0.5;  // [px] Gaussian σ, or the Student-t scale
  double student_nu = 0;     // > 0: pixel noise pixel_sigma · t_ν per coordinate (sim_profile.h)
  double drift_step_px = 0;  // > 0: each track's offset walks by this σ per coordinate and frame
  double cell_fill_probability = 1.0;  // < 1: a free cell yields its new track with this chance
  bool outliers = true;
  double outlier_probability = 0.01;
  double outlier_min_px = 5.0, outlier_max_px = 20.0;
  DetectionPolicy detection = DetectionPolicy::kClosestToCellCentre;
  std::size_t max_frames = 0;  // simulate only the first max_frames frames; 0: all
};

// Grid size from the dataset defaults; max depth 40 m indoor, 250 m KITTI.
TrackerOptions defaultTrackerOptions(const Sequence& sequence);

// Camera pose from a body pose and the camera's extrinsics: T_w_c = T_w_b T_b_c.
inline void cameraPose(const TrajectorySample& body, const CameraCalib& camera,
                       Eigen::Matrix3d* R_w_c, Eigen::Vector3d* p_w_c) {
  *R_w_c = body.R_w_b * camera.R_b_c;
  *p_w_c = body.R_w_b * camera.t_b_c + body.p_w_b;
}

// Simulates tracks at the timestamps of cam_t_ns that lie inside the trajectory's time span.
// Fills frames and landmarks_w (= world.points_w) and seed; sequence is left empty.
TrackStream simulateTracks(const TrajectoryFunction& trajectory, const StereoCalib& calib,
                           const std::vector<int64_t>& cam_t_ns, const World& world,
                           const TrackerOptions& options, uint64_t seed);

struct SimulationOptions {
  WorldOptions world;
  TrackerOptions tracker;
  uint64_t seed = 0;
};
SimulationOptions defaultSimulationOptions(const Sequence& sequence, uint64_t seed = 0);

// World + tracks for a sequence along the given trajectory (normally the TrajectorySpline through
// its ground truth); stream.sequence = sequence.name. Throws InputError when the sequence has no
// trajectory.
TrackStream simulateSequence(const Sequence& sequence, const TrajectoryFunction& trajectory,
                             const SimulationOptions& options);

struct Distribution {
  double mean = 0, median = 0, p90 = 0, min = 0, max = 0;  // p90: nearest rank
};
Distribution distributionOf(std::vector<double> values);

struct TrackStatistics {
  std::size_t frames = 0, observations = 0, tracks = 0;
  Distribution features_per_frame;
  Distribution track_length;  // frames per track id (tracks alive at the end are counted as is)
  double stereo_share = 0;    // observations with has_right
  double outlier_share = 0;   // observations with is_outlier
};
TrackStatistics trackStatistics(const TrackStream& stream);

}  // namespace marglab
