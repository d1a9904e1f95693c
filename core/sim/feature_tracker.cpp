#include "core/sim/feature_tracker.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "core/common/error.h"
#include "core/sim/wall_buffer.h"

namespace marglab {
namespace {

// One camera at one frame: world-to-camera transform and the visibility test.
struct FrameCamera {
  const CameraCalib* calib;
  Eigen::Matrix3d R_c_w;
  Eigen::Vector3d p_w_c;
  double min_depth, max_depth, border;

  FrameCamera(const TrajectorySample& body, const CameraCalib& camera, const TrackerOptions& o)
      : calib(&camera), min_depth(o.min_depth), max_depth(o.max_depth), border(o.border_px) {
    Eigen::Matrix3d R_w_c;
    cameraPose(body, camera, &R_w_c, &p_w_c);
    R_c_w = R_w_c.transpose();
  }

  // Projection of p_w if visible (depth range and image with border).
  bool project(const Eigen::Vector3d& p_w, Eigen::Vector2d* uv,
               Eigen::Vector3d* p_c_out = nullptr) const {
    const Eigen::Vector3d p_c = R_c_w * (p_w - p_w_c);
    if (p_c_out != nullptr) *p_c_out = p_c;
    const double z = p_c.z();
    if (!(z >= min_depth && z <= max_depth)) return false;
    *uv = Eigen::Vector2d(calib->fx * (p_c.x() / z) + calib->cx,
                          calib->fy * (p_c.y() / z) + calib->cy);
    return uv->x() >= border && uv->y() >= border && uv->x() <= calib->width - 1 - border &&
           uv->y() <= calib->height - 1 - border;
  }

  // False if the sphere (centre c_w, radius r) lies entirely outside the view frustum: depth
  // range, and the four side planes u = border, u = w−1−border, v likewise. The side plane
  // u ≥ u_min is fx x + (cx − u_min) z ≥ 0 through the optical centre.
  bool sphereMayBeVisible(const Eigen::Vector3d& c_w, double r) const {
    const Eigen::Vector3d c = R_c_w * (c_w - p_w_c);
    if (c.z() + r < min_depth || c.z() - r > max_depth) return false;
    const double u_min = border, u_max = calib->width - 1 - border;
    const double v_min = border, v_max = calib->height - 1 - border;
    const Eigen::Vector3d planes[4] = {{calib->fx, 0, calib->cx - u_min},
                                       {-calib->fx, 0, u_max - calib->cx},
                                       {0, calib->fy, calib->cy - v_min},
                                       {0, -calib->fy, v_max - calib->cy}};
    for (const Eigen::Vector3d& n : planes) {
      if (n.dot(c) < -r * n.norm()) return false;
    }
    return true;
  }
};

struct ActiveTrack {
  int64_t track_id;
  int64_t landmark_id;
  Eigen::Vector2d drift = Eigen::Vector2d::Zero();  // [px] the realistic profile's walk
};

class Simulator {
 public:
  Simulator(const StereoCalib& calib, const World& world, const TrackerOptions& options,
            uint64_t seed)
      : calib_(calib),
        world_(world),
        o_(options),
        seed_(seed),
        rng_(SimRandom::subSeed(seed, 0x747261636b73)),  // "tracks"
        tracked_(world.points_w.size(), 0),
        cols_(static_cast<int>(std::ceil(calib.cam0.width / options.grid_cell_px))),
        rows_(static_cast<int>(std::ceil(calib.cam0.height / options.grid_cell_px))) {}

  TrackFrame step(int64_t t_ns, const TrajectorySample& body, std::size_t frame_index) {
    const FrameCamera cam0(body, calib_.cam0, o_);
    const FrameCamera cam1(body, calib_.cam1, o_);
    const WallBuffer walls(world_, cam0.R_c_w, cam0.p_w_c, calib_.cam0, cam0.max_depth);
    auto visible0 = [&](int64_t landmark, Eigen::Vector2d* uv0) {
      Eigen::Vector3d p_c;
      return world_.facing(landmark, cam0.p_w_c) &&
             cam0.project(world_.points_w[landmark], uv0, &p_c) && !walls.hidden(p_c, *uv0);
    };
    TrackFrame frame;
    frame.t_ns = t_ns;

    // 1. Continue the active tracks.
    std::vector<ActiveTrack> kept;
    kept.reserve(active_.size());
    std::vector<char> occupied(static_cast<std::size_t>(cols_ * rows_), 0);
    for (ActiveTrack track : active_) {
      Eigen::Vector2d uv0;
      const Eigen::Vector3d& p_w = world_.points_w[track.landmark_id];
      if (!visible0(track.landmark_id, &uv0) || rng_.bernoulli(o_.loss_probability)) {
        tracked_[track.landmark_id] = 0;
        continue;
      }
      if (o_.drift_step_px > 0) {
        const double du = rng_.normal();
        const double dv = rng_.normal();
        track.drift += o_.drift_step_px * Eigen::Vector2d(du, dv);
      }
      kept.push_back(track);
      frame.observations.push_back(measure(track, uv0, p_w, cam1));
      const int cell = cellOf(frame.observations.back().uv0);
      if (cell >= 0) occupied[cell] = 1;
    }

    // 2. Detect in the free cells.
    constexpr double kNone = std::numeric_limits<double>::infinity();
    std::vector<std::pair<double, int64_t>> best(occupied.size(), {kNone, -1});
    for (const WorldChunk& chunk : world_.chunks) {
      if (!cam0.sphereMayBeVisible(chunk.centre, chunk.radius)) continue;
      for (uint32_t i = chunk.begin; i < chunk.end; ++i) {
        if (tracked_[i]) continue;
        Eigen::Vector2d uv;
        if (!visible0(i, &uv)) continue;
        const int cell = cellOf(uv);
        if (cell < 0 || occupied[cell]) continue;
        double score;
        if (o_.detection == DetectionPolicy::kClosestToCellCentre) {
          const Eigen::Vector2d centre((cell % cols_ + 0.5) * o_.grid_cell_px,
                                       (cell / cols_ + 0.5) * o_.grid_cell_px);
          score = (uv - centre).squaredNorm();
        } else {
          score = static_cast<double>(
              SimRandom::subSeed(seed_ ^ (frame_index << 32), static_cast<uint64_t>(i) + 1) >> 11);
        }
        if (score < best[cell].first) best[cell] = {score, static_cast<int64_t>(i)};
      }
    }
    for (const auto& [score, landmark] : best) {
      if (landmark < 0) continue;
      if (o_.cell_fill_probability < 1 && !rng_.bernoulli(o_.cell_fill_probability)) continue;
      const ActiveTrack track{next_track_id_++, landmark};
      tracked_[landmark] = 1;
      kept.push_back(track);
      Eigen::Vector2d uv0;
      const Eigen::Vector3d& p_w = world_.points_w[landmark];
      cam0.project(p_w, &uv0);
      frame.observations.push_back(measure(track, uv0, p_w, cam1));
    }
    active_ = std::move(kept);
    return frame;
  }

 private:
  int cellOf(const Eigen::Vector2d& uv) const {
    const int i = static_cast<int>(std::floor(uv.x() / o_.grid_cell_px));
    const int j = static_cast<int>(std::floor(uv.y() / o_.grid_cell_px));
    if (i < 0 || j < 0 || i >= cols_ || j >= rows_) return -1;
    return j * cols_ + i;
  }

  Eigen::Vector2d pixelNoise() {
    if (!o_.noise) return Eigen::Vector2d::Zero();
    if (o_.student_nu > 0) {
      const double tu = rng_.studentT(o_.student_nu);
      const double tv = rng_.studentT(o_.student_nu);
      return o_.pixel_sigma * Eigen::Vector2d(tu, tv);
    }
    const double nu = rng_.normal();
    const double nv = rng_.normal();
    return o_.pixel_sigma * Eigen::Vector2d(nu, nv);
  }

  Eigen::Vector2d displaced(const Eigen::Vector2d& uv, const CameraCalib& camera) {
    const double r = rng_.uniform(o_.outlier_min_px, o_.outlier_max_px);
    const double phi = rng_.uniform(0, 2 * SimRandom::kPi);
    const Eigen::Vector2d out = uv + r * Eigen::Vector2d(std::cos(phi), std::sin(phi));
    return Eigen::Vector2d(std::clamp(out.x(), 0.0, camera.width - 1.0),
                           std::clamp(out.y(), 0.0, camera.height - 1.0));
  }

  StereoObservation measure(const ActiveTrack& track, const Eigen::Vector2d& uv0_true,
                            const Eigen::Vector3d& p_w, const FrameCamera& cam1) {
    StereoObservation obs;
    obs.track_id = track.track_id;
    obs.landmark_id = track.landmark_id;
    obs.uv0 = uv0_true + pixelNoise();
    if (o_.drift_step_px > 0) obs.uv0 += track.drift;
    Eigen::Vector2d uv1;
    if (world_.facing(track.landmark_id, cam1.p_w_c) && cam1.project(p_w, &uv1) &&
        !rng_.bernoulli(o_.stereo_failure_probability)) {
      obs.has_right = true;
      obs.uv1 = uv1 + pixelNoise();
      if (o_.drift_step_px > 0) obs.uv1 += track.drift;
    }
    if (o_.outliers && rng_.bernoulli(o_.outlier_probability)) {
      obs.is_outlier = true;
      obs.uv0 = displaced(obs.uv0, calib_.cam0);
      if (obs.has_right) obs.uv1 = displaced(obs.uv1, calib_.cam1);
    }
    return obs;
  }

  const StereoCalib& calib_;
  const World& world_;
  const TrackerOptions& o_;
  uint64_t seed_;
  SimRandom rng_;
  std::vector<char> tracked_;  // per landmark: currently tracked
  std::vector<ActiveTrack> active_;
  int64_t next_track_id_ = 0;
  int cols_, rows_;
};

}  // namespace

TrackerOptions defaultTrackerOptions(const Sequence& sequence) {
  TrackerOptions o;
  o.grid_cell_px = sequence.defaults.grid_cell_px;
  if (sequence.kind == DatasetKind::kKitti) o.max_depth = 250.0;
  return o;
}

TrackStream simulateTracks(const TrajectoryFunction& trajectory, const StereoCalib& calib,
                           const std::vector<int64_t>& cam_t_ns, const World& world,
                           const TrackerOptions& options, uint64_t seed) {
  TrackStream stream;
  stream.seed = seed;
  stream.landmarks_w = world.points_w;
  Simulator simulator(calib, world, options, seed);
  for (const int64_t t_ns : cam_t_ns) {
    if (t_ns < trajectory.startTimeNs() || t_ns > trajectory.endTimeNs()) continue;
    if (options.max_frames > 0 && stream.frames.size() >= options.max_frames) break;
    stream.frames.push_back(simulator.step(t_ns, trajectory.evaluate(t_ns), stream.frames.size()));
  }
  return stream;
}

SimulationOptions defaultSimulationOptions(const Sequence& sequence, uint64_t seed) {
  SimulationOptions o;
  o.world = defaultWorldOptions(sequence.kind);
  o.tracker = defaultTrackerOptions(sequence);
  o.seed = seed;
  return o;
}

TrackStream simulateSequence(const Sequence& sequence, const TrajectoryFunction& trajectory,
                             const SimulationOptions& options) {
  if (!sequence.hasTrajectory()) {
    throw InputError(
        sequence.directory, 0,
        fmt::format("{}: no trajectory (timestamps only); cannot simulate", sequence.name));
  }
  World world;
  try {
    world = makeWorld(trajectory, options.world, options.seed);
  } catch (const InputError& e) {
    throw InputError(sequence.gt_file, 0, e.detail());
  }
  TrackStream stream = simulateTracks(trajectory, sequence.calib, sequence.cam_t_ns, world,
                                      options.tracker, options.seed);
  stream.sequence = sequence.name;
  return stream;
}

Distribution distributionOf(std::vector<double> values) {
  Distribution d;
  if (values.empty()) return d;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  double sum = 0;
  for (const double v : values) sum += v;
  d.mean = sum / static_cast<double>(n);
  d.median = n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
  d.p90 = values[static_cast<std::size_t>(std::ceil(0.9 * static_cast<double>(n))) - 1];
  d.min = values.front();
  d.max = values.back();
  return d;
}

TrackStatistics trackStatistics(const TrackStream& stream) {
  TrackStatistics s;
  s.frames = stream.frames.size();
  std::vector<double> per_frame;
  std::unordered_map<int64_t, double> length;
  std::size_t stereo = 0, outliers = 0;
  for (const TrackFrame& frame : stream.frames) {
    per_frame.push_back(static_cast<double>(frame.observations.size()));
    for (const StereoObservation& obs : frame.observations) {
      length[obs.track_id] += 1;
      stereo += obs.has_right ? 1 : 0;
      outliers += obs.is_outlier ? 1 : 0;
    }
    s.observations += frame.observations.size();
  }
  s.tracks = length.size();
  std::vector<double> lengths;
  lengths.reserve(length.size());
  for (const auto& [id, n] : length) lengths.push_back(n);
  s.features_per_frame = distributionOf(std::move(per_frame));
  s.track_length = distributionOf(std::move(lengths));
  if (s.observations > 0) {
    s.stereo_share = static_cast<double>(stereo) / static_cast<double>(s.observations);
    s.outlier_share = static_cast<double>(outliers) / static_cast<double>(s.observations);
  }
  return s;
}

}  // namespace marglab
