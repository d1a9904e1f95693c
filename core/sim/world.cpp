#include "core/sim/world.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <string>
#include <unordered_map>

#include <fmt/core.h>

#include "core/common/error.h"

namespace marglab {
namespace {

struct PathSample {
  Eigen::Vector3d p_w;
  Eigen::Matrix3d R_w_b;
};

// The path resampled so that consecutive samples are at most max_step metres apart (and at least
// one sample per second, so that hovering is represented once per second).
std::vector<PathSample> samplePath(const TrajectoryFunction& trajectory, double max_step) {
  std::vector<PathSample> samples;
  const int64_t t0 = trajectory.startTimeNs();
  const int64_t t1 = trajectory.endTimeNs();
  const int64_t dt = 10 * 1000 * 1000;  // 10 ms: fine enough for 25 m/s at 0.25 m steps
  int64_t last_kept = t0;
  for (int64_t t = t0;; t = std::min(t + dt, t1)) {
    const TrajectorySample s = trajectory.evaluate(t);
    if (samples.empty() || t == t1 || (s.p_w_b - samples.back().p_w).norm() >= max_step ||
        t - last_kept >= 1000 * 1000 * 1000) {
      samples.push_back({s.p_w_b, s.R_w_b});
      last_kept = t;
    }
    if (t == t1) break;
  }
  return samples;
}

// Refuses a world larger than options.max_points before it is built (an implausible trajectory
// would otherwise take memory without bound).
void checkWorldSize(double points, const WorldOptions& options, const std::string& extent) {
  if (points <= options.max_points) return;
  throw InputError("", 0,
                   fmt::format("the simulated world would hold about {:.3g} points ({}), more "
                               "than the limit of {:.3g}: is the trajectory plausible?",
                               points, extent, options.max_points));
}

// Hash grid over path positions for "is q within r of the path" queries. With horizontal = true
// distances are measured in the plane orthogonal to up (the component along up is dropped).
class PathIndex {
 public:
  PathIndex(const std::vector<PathSample>& path, double radius, bool horizontal,
            const Eigen::Vector3d& up)
      : radius_(radius), horizontal_(horizontal), up_(up.normalized()) {
    for (const PathSample& s : path) {
      const Eigen::Vector3d q = reduce(s.p_w);
      cells_[key(cellOf(q))].push_back(q);
    }
  }

  bool near(const Eigen::Vector3d& p_w) const {
    const Eigen::Vector3d q = reduce(p_w);
    const Eigen::Vector3i c = cellOf(q);
    const double r2 = radius_ * radius_;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = cells_.find(key(c + Eigen::Vector3i(dx, dy, dz)));
          if (it == cells_.end()) continue;
          for (const Eigen::Vector3d& s : it->second) {
            if ((s - q).squaredNorm() < r2) return true;
          }
        }
      }
    }
    return false;
  }

 private:
  Eigen::Vector3d reduce(const Eigen::Vector3d& p) const {
    return horizontal_ ? Eigen::Vector3d(p - up_.dot(p) * up_) : p;
  }
  Eigen::Vector3i cellOf(const Eigen::Vector3d& q) const {
    return (q / radius_).array().floor().cast<int>();
  }
  static int64_t key(const Eigen::Vector3i& c) {
    return (static_cast<int64_t>(c.x()) * 73856093) ^ (static_cast<int64_t>(c.y()) * 19349663) ^
           (static_cast<int64_t>(c.z()) * 83492791);
  }

  double radius_;
  bool horizontal_;
  Eigen::Vector3d up_;
  std::unordered_map<int64_t, std::vector<Eigen::Vector3d>> cells_;
};

struct Cloud {
  std::vector<Eigen::Vector3d> points, normals;
  std::vector<WallSegment> walls;
  void add(const Eigen::Vector3d& p, const Eigen::Vector3d& n) {
    points.push_back(p);
    normals.push_back(n);
  }
};

// round(area · density) points uniformly on the parallelogram o + [0,1] a + [0,1] b, facing n.
void addRectangle(const Eigen::Vector3d& o, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                  const Eigen::Vector3d& n, double density, SimRandom& rng, Cloud* cloud) {
  const auto count = static_cast<int64_t>(std::llround(a.cross(b).norm() * density));
  for (int64_t i = 0; i < count; ++i) {
    const double u = rng.uniform();
    const double v = rng.uniform();
    cloud->add(o + u * a + v * b, n);
  }
}

// Points on the 5 visible faces (not the bottom) of the axis-aligned box [lo, hi], facing out.
void addBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double density, SimRandom& rng,
            Cloud* cloud) {
  const Eigen::Vector3d d = hi - lo;
  const Eigen::Vector3d ex(d.x(), 0, 0), ey(0, d.y(), 0), ez(0, 0, d.z());
  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY();
  addRectangle(lo, ex, ez, -Y, density, rng, cloud);
  addRectangle(lo + ey, ex, ez, Y, density, rng, cloud);
  addRectangle(lo, ey, ez, -X, density, rng, cloud);
  addRectangle(lo + ex, ey, ez, X, density, rng, cloud);
  addRectangle(lo + ez, ex, ey, Eigen::Vector3d::UnitZ(), density, rng, cloud);
}

Cloud indoorPoints(const std::vector<PathSample>& path, const WorldOptions& o, SimRandom& rng) {
  Eigen::Vector3d lo = path.front().p_w, hi = path.front().p_w;
  for (const PathSample& s : path) {
    lo = lo.cwiseMin(s.p_w);
    hi = hi.cwiseMax(s.p_w);
  }
  lo -= Eigen::Vector3d(o.horizontal_margin, o.horizontal_margin, o.floor_margin);
  hi += Eigen::Vector3d(o.horizontal_margin, o.horizontal_margin, o.ceiling_margin);
  const Eigen::Vector3d d = hi - lo;
  const double box_points = 5 * o.clutter_box_max * o.clutter_box_max * o.surface_density;
  checkWorldSize(2 * (d.x() * d.y() + d.x() * d.z() + d.y() * d.z()) * o.surface_density +
                     d.x() * d.y() * o.clutter_boxes_per_m2 * box_points +
                     d.prod() * o.clutter_point_density,
                 o, fmt::format("a room of {:.3g} x {:.3g} x {:.3g} m", d.x(), d.y(), d.z()));
  const Eigen::Vector3d ex(d.x(), 0, 0), ey(0, d.y(), 0), ez(0, 0, d.z());

  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(),
                        Z = Eigen::Vector3d::UnitZ();
  const double density = o.surface_density;
  Cloud cloud;                                              // room surfaces face inwards
  addRectangle(lo, ex, ey, Z, density, rng, &cloud);        // floor
  addRectangle(lo + ez, ex, ey, -Z, density, rng, &cloud);  // ceiling
  addRectangle(lo, ex, ez, Y, density, rng, &cloud);        // walls
  addRectangle(lo + ey, ex, ez, -Y, density, rng, &cloud);
  addRectangle(lo, ey, ez, X, density, rng, &cloud);
  addRectangle(lo + ex, ey, ez, -X, density, rng, &cloud);

  // Clutter boxes on the floor, kept path_clearance away from every path sample.
  const auto boxes = static_cast<int64_t>(std::llround(d.x() * d.y() * o.clutter_boxes_per_m2));
  for (int64_t i = 0; i < boxes; ++i) {
    for (int attempt = 0; attempt < 20; ++attempt) {
      Eigen::Vector3d size(rng.uniform(o.clutter_box_min, o.clutter_box_max),
                           rng.uniform(o.clutter_box_min, o.clutter_box_max),
                           rng.uniform(o.clutter_box_min, o.clutter_box_max));
      size = size.cwiseMin(d);
      const Eigen::Vector3d box_lo(rng.uniform(lo.x(), hi.x() - size.x()),
                                   rng.uniform(lo.y(), hi.y() - size.y()), lo.z());
      const Eigen::Vector3d box_hi = box_lo + size;
      const bool clear = std::none_of(path.begin(), path.end(), [&](const PathSample& s) {
        const Eigen::Vector3d gap =
            (box_lo - s.p_w).cwiseMax(s.p_w - box_hi).cwiseMax(Eigen::Vector3d::Zero());
        return gap.norm() < o.path_clearance;
      });
      if (clear) {
        addBox(box_lo, box_hi, density, rng, &cloud);
        break;
      }
    }
  }

  // Free points (pipes, railings, lamps) in the room volume, away from the path.
  const PathIndex index(path, o.path_clearance, false, Eigen::Vector3d::UnitZ());
  const auto free_points =
      static_cast<int64_t>(std::llround(d.x() * d.y() * d.z() * o.clutter_point_density));
  for (int64_t i = 0; i < free_points; ++i) {
    const Eigen::Vector3d p(rng.uniform(lo.x(), hi.x()), rng.uniform(lo.y(), hi.y()),
                            rng.uniform(lo.z(), hi.z()));
    if (!index.near(p)) cloud.add(p, Eigen::Vector3d::Zero());
  }
  return cloud;
}

// Stations every station_spacing metres of arc length.
std::vector<const PathSample*> streetStations(const std::vector<PathSample>& path, double spacing) {
  std::vector<const PathSample*> stations{&path.front()};
  double arc = 0;
  for (std::size_t i = 1; i < path.size(); ++i) {
    arc += (path[i].p_w - path[i - 1].p_w).norm();
    if (arc >= spacing) {
      stations.push_back(&path[i]);
      arc = 0;
    }
  }
  return stations;
}

// The street between two stations: forward f and left l in the plane normal to up u, the ground
// point g below the camera, and the length of the section.
struct StreetSection {
  Eigen::Vector3d f, l, u, g;
  double step = 0;
};

struct Building {
  double remaining = 0;  // [m] until the next building starts
  double offset = 0;     // 0: gap
};

// One side's building along a section (sign +1: left, −1: right): a new building or gap where the
// last one ended, its wall and facade points. Returns the ground's extent on that side.
double addBuildingSide(Building& b, double sign, const StreetSection& sec, const WorldOptions& o,
                       const PathIndex& index, SimRandom& rng, Cloud* cloud) {
  const Eigen::Vector3d &f = sec.f, &l = sec.l, &u = sec.u, &g = sec.g;
  if (b.remaining <= 0) {
    b.remaining = rng.uniform(o.building_length_min, o.building_length_max);
    b.offset = rng.bernoulli(o.facade_gap_probability)
                   ? 0.0
                   : rng.uniform(o.facade_offset_min, o.facade_offset_max);
  }
  b.remaining -= sec.step;
  if (b.offset <= 0) return o.ground_half_width;
  // The wall occludes only where it is away from the path (as its points).
  const WallSegment wall{g + sign * b.offset * l, g + sign * b.offset * l + sec.step * f};
  if (!index.near(wall.a_w) && !index.near(wall.b_w) && !index.near(0.5 * (wall.a_w + wall.b_w))) {
    cloud->walls.push_back(wall);
  }
  const auto n = static_cast<int64_t>(std::llround(sec.step * o.facade_height * o.facade_density));
  for (int64_t i = 0; i < n; ++i) {
    const Eigen::Vector3d q = g + sign * b.offset * l + rng.uniform(0, o.facade_height) * u +
                              rng.uniform(0, sec.step) * f;
    if (!index.near(q)) cloud->add(q, -sign * l);
  }
  return std::min(b.offset, o.ground_half_width);
}

// The ground between the two sides' extents and the far points of a section.
void addGroundAndFarPoints(const StreetSection& sec, const double ground_extent[2],
                           const WorldOptions& o, const PathIndex& index, SimRandom& rng,
                           Cloud* cloud) {
  const Eigen::Vector3d &f = sec.f, &l = sec.l, &u = sec.u, &g = sec.g;
  const double width = ground_extent[0] + ground_extent[1];
  const auto n_ground = static_cast<int64_t>(std::llround(sec.step * width * o.ground_density));
  for (int64_t i = 0; i < n_ground; ++i) {
    cloud->add(
        g + rng.uniform(-ground_extent[1], ground_extent[0]) * l + rng.uniform(0, sec.step) * f, u);
  }
  // Far points: a Poisson-like count with the requested mean (floor + Bernoulli remainder).
  const double mean_far = o.far_points_per_station * sec.step / o.station_spacing;
  const auto n_far =
      static_cast<int64_t>(mean_far) + (rng.bernoulli(mean_far - std::floor(mean_far)) ? 1 : 0);
  for (int64_t i = 0; i < n_far; ++i) {
    const double r = rng.uniform(o.far_min, o.far_max);
    const double phi = rng.uniform(0, 2 * SimRandom::kPi);
    const Eigen::Vector3d q =
        g + r * (std::cos(phi) * f + std::sin(phi) * l) + rng.uniform(0, o.far_height) * u;
    if (!index.near(q)) cloud->add(q, Eigen::Vector3d::Zero());
  }
}

Cloud streetPoints(const std::vector<PathSample>& path, const WorldOptions& o, SimRandom& rng) {
  const std::vector<const PathSample*> stations = streetStations(path, o.station_spacing);
  double length = 0;
  for (std::size_t k = 1; k < stations.size(); ++k) {
    length += (stations[k]->p_w - stations[k - 1]->p_w).norm();
  }
  checkWorldSize(length * (2 * o.facade_height * o.facade_density +
                           2 * o.ground_half_width * o.ground_density +
                           o.far_points_per_station / o.station_spacing),
                 o, fmt::format("a street of {:.3g} m", length));
  Eigen::Vector3d mean_up = Eigen::Vector3d::Zero();
  for (const PathSample* s : stations) mean_up += s->R_w_b * o.up_b;
  const PathIndex index(path, o.path_clearance, true, mean_up);

  Cloud cloud;
  Building side[2];
  for (std::size_t k = 0; k + 1 < stations.size(); ++k) {
    StreetSection sec;
    const Eigen::Vector3d p = stations[k]->p_w;
    sec.u = (stations[k]->R_w_b * o.up_b).normalized();
    sec.f = stations[k + 1]->p_w - p;
    sec.step = sec.f.norm();
    sec.f -= sec.u.dot(sec.f) * sec.u;
    if (!(sec.f.norm() > 1e-6 * std::max(sec.step, 1.0))) continue;
    sec.f.normalize();
    sec.l = sec.u.cross(sec.f);
    sec.g = p - o.camera_height * sec.u;
    double ground_extent[2];
    for (int s = 0; s < 2; ++s) {
      ground_extent[s] = addBuildingSide(side[s], s == 0 ? 1.0 : -1.0, sec, o, index, rng, &cloud);
    }
    addGroundAndFarPoints(sec, ground_extent, o, index, rng, &cloud);
  }
  return cloud;
}

}  // namespace

WorldOptions defaultWorldOptions(DatasetKind kind) {
  WorldOptions o;
  if (kind == DatasetKind::kKitti) {
    o.kind = WorldKind::kStreet;
    o.path_clearance = 4.0;
  }
  return o;
}

World indexWorld(const std::vector<Eigen::Vector3d>& points_w,
                 const std::vector<Eigen::Vector3d>& normals_w, double chunk_size) {
  using Key = std::array<int64_t, 3>;
  std::vector<Key> keys(points_w.size());
  for (std::size_t i = 0; i < points_w.size(); ++i) {
    const Eigen::Vector3d c = (points_w[i] / chunk_size).array().floor();
    keys[i] = {static_cast<int64_t>(c.x()), static_cast<int64_t>(c.y()),
               static_cast<int64_t>(c.z())};
  }
  std::vector<uint32_t> order(points_w.size());
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t b) { return keys[a] < keys[b]; });

  World world;
  world.points_w.reserve(points_w.size());
  world.normals_w.reserve(points_w.size());
  for (std::size_t i = 0; i < order.size(); ++i) {
    if (i == 0 || keys[order[i]] != keys[order[i - 1]]) {
      world.chunks.push_back({});
      world.chunks.back().begin = static_cast<uint32_t>(i);
    }
    world.points_w.push_back(points_w[order[i]]);
    world.normals_w.push_back(normals_w.empty() ? Eigen::Vector3d::Zero() : normals_w[order[i]]);
    world.chunks.back().end = static_cast<uint32_t>(i + 1);
  }
  for (WorldChunk& chunk : world.chunks) {
    Eigen::Vector3d lo = world.points_w[chunk.begin], hi = lo;
    for (uint32_t i = chunk.begin; i < chunk.end; ++i) {
      lo = lo.cwiseMin(world.points_w[i]);
      hi = hi.cwiseMax(world.points_w[i]);
    }
    chunk.centre = 0.5 * (lo + hi);
    chunk.radius = 0.5 * (hi - lo).norm();
  }
  return world;
}

World makeWorld(const TrajectoryFunction& trajectory, const WorldOptions& options, uint64_t seed) {
  SimRandom rng(SimRandom::subSeed(seed, 0x776f726c64));  // "world"
  const std::vector<PathSample> path = samplePath(trajectory, 0.25);
  const Cloud cloud = options.kind == WorldKind::kIndoor ? indoorPoints(path, options, rng)
                                                         : streetPoints(path, options, rng);
  World world =
      indexWorld(cloud.points, cloud.normals, options.kind == WorldKind::kIndoor ? 4.0 : 10.0);
  world.walls = cloud.walls;
  return world;
}

}  // namespace marglab
