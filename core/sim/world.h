#pragma once
// Simulated 3-D world: points on the surfaces around a trajectory (docs/design.md §5),
// deterministic for a seed, and a chunked spatial index for the per-frame visibility query of the
// tracker.
//
// Indoor (EuRoC machine hall / Vicon room, TUM-VI): the axis-aligned box B = bbox(path) grown
//   by a horizontal margin, floor_margin below and ceiling_margin above (world z is up, the
//   mocap frames are gravity aligned). Its 4 walls, floor and ceiling carry points uniformly at
//   surface_density [1/m²] (Poisson-like: count = round(area · density), positions uniform).
//   Clutter: boxes standing on the floor (sides uniform in [clutter_box_min, clutter_box_max],
//   5 faces, same surface density) and free points in the room volume (clutter_point_density
//   [1/m³]); both are rejected when closer than path_clearance to the path.
// Street (KITTI): the path is resampled every station_spacing metres of arc length. At each
//   station s with position p, forward f (direction to the next station, made orthogonal to up),
//   up u = R_w_b up_b (KITTI body = cam0, up_b = (0, −1, 0)), lateral l = u × f and ground
//   g = p − camera_height u:
//     facades  on both sides, p_w = g + side · d · l + h u + t f, h ∈ [0, facade_height],
//              t ∈ [0, spacing); the offset d ∈ [facade_offset_min, facade_offset_max] is constant
//              over a "building" of random length [building_length_min, max] and a building is a
//              gap (no facade) with probability facade_gap_probability;
//     ground   p_w = g + a l + t f, a uniform in ±ground_half_width;
//     far      p_w = g + r (cos φ f + sin φ l) + h u, r ∈ [far_min, far_max], φ uniform,
//              h ∈ [0, far_height] (trees, hills and buildings far away).
//   Facade and ground points closer than path_clearance (ground: measured horizontally) to any
//   part of the path are dropped, so that crossing streets do not wall in the road.
// Occlusion, two cheap models:
//   back-face culling: surface points carry the surface normal n (walls, floor and ceiling facing
//     into the room, box faces and facades facing out / towards the road, ground up); such a
//     point is visible only from the front side, (p_c − p_w)·n ≥ 0. Free and far points have
//     n = 0 (visible from everywhere).
//   walls (street): each facade piece is also an occluding vertical wall segment (its ground
//     line, infinitely tall), so that the facades of other streets and far points behind
//     buildings are hidden; the tracker tests this in a horizontal depth buffer
//     (feature_tracker.h).
//   Indoor clutter boxes do not occlude.
//
// Random numbers: std::mt19937_64 with our own uniform / normal transforms (SimRandom), so that
// a seed yields the same world and tracks on every platform.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/data/types.h"
#include "core/sim/trajectory_spline.h"

namespace marglab {

// Platform-independent random numbers: mt19937_64 is fully specified by the standard; the
// transforms below are ours (std::*_distribution are implementation defined).
class SimRandom {
 public:
  static constexpr double kPi = 3.14159265358979323846;
  explicit SimRandom(uint64_t seed) : engine_(seed) {}
  // Uniform in [0, 1), 53 random bits.
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // Uniform integer in [0, n), n > 0 (modulo; bias < n / 2⁶⁴).
  uint64_t index(uint64_t n) { return engine_() % n; }
  bool bernoulli(double p) { return uniform() < p; }
  // Standard normal by Box–Muller (one value per call, two uniforms; no cached state).
  double normal() {
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
  }
  // Gamma(shape, 1), shape > 0: Marsaglia–Tsang (2000) for shape ≥ 1, and Gamma(shape + 1)
  // U^{1/shape} below 1 (normal() and uniform() only, so the stream is platform independent).
  double gamma(double shape) {
    if (shape < 1) return gamma(shape + 1) * std::pow(1.0 - uniform(), 1.0 / shape);
    const double d = shape - 1.0 / 3.0, c = 1.0 / std::sqrt(9 * d);
    for (;;) {
      const double x = normal();
      const double v = std::pow(1 + c * x, 3);
      if (v <= 0) continue;
      const double u = 1.0 - uniform();  // (0, 1]
      if (std::log(u) < 0.5 * x * x + d - d * v + d * std::log(v)) return d * v;
    }
  }
  // Student-t with nu > 0 degrees of freedom: z / sqrt(g / (nu/2)), g ~ Gamma(nu/2, 1), so that
  // 2g is χ²_ν.
  double studentT(double nu) {
    const double z = normal();
    return z / std::sqrt(2 * gamma(0.5 * nu) / nu);
  }
  // Derives an independent seed for a named sub-stream (SplitMix64 finalizer of seed ^ salt).
  static uint64_t subSeed(uint64_t seed, uint64_t salt) {
    uint64_t z = seed ^ (salt * 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }

 private:
  std::mt19937_64 engine_;
};

enum class WorldKind { kIndoor, kStreet };

struct WorldOptions {
  WorldKind kind = WorldKind::kIndoor;
  double path_clearance = 1.0;  // [m] no point closer than this to the path
  // Indoor.
  double horizontal_margin = 2.0;      // [m] walls beyond the path's bounding box
  double floor_margin = 0.3;           // [m] floor below the lowest path point
  double ceiling_margin = 2.0;         // [m] ceiling above the highest path point
  double surface_density = 20.0;       // [1/m²] walls, floor, ceiling, clutter boxes
  double clutter_boxes_per_m2 = 0.03;  // boxes per m² of floor
  double clutter_box_min = 0.4, clutter_box_max = 2.5;  // [m]
  double clutter_point_density = 0.5;                   // [1/m³] free points in the room
  // Street.
  Eigen::Vector3d up_b = Eigen::Vector3d(0, -1, 0);               // body up (KITTI cam0: y down)
  double camera_height = 1.65;                                    // [m] body above the ground
  double station_spacing = 2.0;                                   // [m] of arc length
  double facade_offset_min = 5.0, facade_offset_max = 12.0;       // [m] lateral
  double facade_height = 15.0;                                    // [m]
  double building_length_min = 10.0, building_length_max = 40.0;  // [m]
  double facade_gap_probability = 0.15;
  double facade_density = 0.5;                                // [1/m²]
  double ground_half_width = 10.0;                            // [m]
  double ground_density = 0.15;                               // [1/m²]
  double far_min = 50.0, far_max = 200.0, far_height = 30.0;  // [m]
  double far_points_per_station = 3.0;
  // Bound on the world's size, checked before it is built: ~25× the largest shipped world
  // (KITTI 02, EuRoC machine hall: ~10⁵ points), ~0.25 GB with the normals.
  double max_points = 5e6;
};

// Dataset defaults (tuned for 100–250 tracked features per frame, see datasets/README.md).
WorldOptions defaultWorldOptions(DatasetKind kind);

// A block of consecutive points with a bounding sphere: the unit of visibility culling.
struct WorldChunk {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0;
  uint32_t begin = 0, end = 0;  // [begin, end) into World::points_w
};

// An occluding vertical wall: the ground segment a_w–b_w extruded upwards without limit.
struct WallSegment {
  Eigen::Vector3d a_w = Eigen::Vector3d::Zero(), b_w = Eigen::Vector3d::Zero();
};

struct World {
  std::vector<Eigen::Vector3d> points_w;   // landmark_id indexes this
  std::vector<Eigen::Vector3d> normals_w;  // unit surface normal, or zero (no facing)
  std::vector<WorldChunk> chunks;          // cover points_w exactly, in order
  std::vector<WallSegment> walls;          // occluders (street worlds)

  // Back-face test for a camera centre p_w_c.
  bool facing(std::size_t i, const Eigen::Vector3d& p_w_c) const {
    return normals_w[i].dot(p_w_c - points_w[i]) >= 0;
  }
};

// Builds the world around the trajectory (sampled over its whole time span: what a short run sees
// depends on the streets driven later, so the world does not depend on the frames a run uses).
// Deterministic for (trajectory, options, seed). Throws InputError (no file) when the world would
// exceed options.max_points, before building it.
World makeWorld(const TrajectoryFunction& trajectory, const WorldOptions& options, uint64_t seed);

// Groups points into chunks by cubic voxel of side chunk_size (stable within a voxel), reorders
// points_w and normals_w (same size, or empty: all zero) accordingly and fills chunks. Exposed
// for tests and hand-made worlds.
World indexWorld(const std::vector<Eigen::Vector3d>& points_w,
                 const std::vector<Eigen::Vector3d>& normals_w = {}, double chunk_size = 8.0);

}  // namespace marglab
