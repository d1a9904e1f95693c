// Simulated stereo tracking (core/sim/feature_tracker.h) on analytic trajectories with the real
// EuRoC and KITTI calibrations: exact noise-free projections, determinism, noise and outlier
// statistics, grid detection, and the track statistics targets.

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/trajectory_spline.h"
#include "sim_test_utils.h"

namespace marglab {
namespace {

struct Scenario {
  const char* name;
  const char* sequence;  // whose calibration and defaults are used
  bool indoor;
};

class TrackerScenario : public ::testing::TestWithParam<Scenario> {
 protected:
  void SetUp() override {
    sequence_ = loadSequence(GetParam().sequence, LoadOptions{false});
    if (GetParam().indoor) {
      trajectory_ = std::make_unique<test::IndoorLoop>(30.0);
      times_ = test::uniformTimes(trajectory_->endTimeNs(), 50'000'000);  // 20 Hz
    } else {
      trajectory_ = std::make_unique<test::StreetDrive>(30.0);
      times_ = test::uniformTimes(trajectory_->endTimeNs(), 100'000'000);  // 10 Hz
    }
    options_ = defaultSimulationOptions(sequence_, 11);
    world_ = makeWorld(*trajectory_, options_.world, options_.seed);
  }
  TrackStream simulate(const TrackerOptions& tracker, uint64_t seed) const {
    return simulateTracks(*trajectory_, sequence_.calib, times_, world_, tracker, seed);
  }

  Sequence sequence_;
  std::unique_ptr<TrajectoryFunction> trajectory_;
  std::vector<int64_t> times_;
  SimulationOptions options_;
  World world_;
};

// Independent projection: p_c = (R_w_b R_b_c)ᵀ (p_w − (R_w_b t_b_c + p_w_b)), pinhole.
Eigen::Vector2d projectTrue(const TrajectorySample& body, const CameraCalib& cam,
                            const Eigen::Vector3d& p_w, double* depth) {
  const Eigen::Matrix3d R_w_c = body.R_w_b * cam.R_b_c;
  const Eigen::Vector3d p_w_c = body.R_w_b * cam.t_b_c + body.p_w_b;
  const Eigen::Vector3d p_c = R_w_c.transpose() * (p_w - p_w_c);
  *depth = p_c.z();
  return Eigen::Vector2d(cam.fx * p_c.x() / p_c.z() + cam.cx, cam.fy * p_c.y() / p_c.z() + cam.cy);
}

TEST_P(TrackerScenario, NoiseFreeObservationsAreExactProjections) {
  TrackerOptions tracker = options_.tracker;
  tracker.noise = false;
  tracker.outliers = false;
  const TrackStream stream = simulate(tracker, 1);
  ASSERT_EQ(stream.frames.size(), times_.size());
  ASSERT_EQ(stream.landmarks_w.size(), world_.points_w.size());
  std::size_t checked = 0, checked_right = 0;
  for (const TrackFrame& frame : stream.frames) {
    const TrajectorySample body = trajectory_->evaluate(frame.t_ns);
    for (const StereoObservation& obs : frame.observations) {
      ASSERT_FALSE(obs.is_outlier);
      const Eigen::Vector3d& p_w = stream.landmarks_w.at(obs.landmark_id);
      double z0 = 0;
      const Eigen::Vector2d uv0 = projectTrue(body, sequence_.calib.cam0, p_w, &z0);
      ASSERT_LT((uv0 - obs.uv0).norm(), 1e-9) << obs.track_id;
      ASSERT_GE(z0, tracker.min_depth);
      ASSERT_LE(z0, tracker.max_depth);
      ++checked;
      if (obs.has_right) {
        double z1 = 0;
        const Eigen::Vector2d uv1 = projectTrue(body, sequence_.calib.cam1, p_w, &z1);
        ASSERT_LT((uv1 - obs.uv1).norm(), 1e-9) << obs.track_id;
        ASSERT_GT(z1, 0);
        ++checked_right;
      }
    }
  }
  EXPECT_GT(checked, 1000u);
  EXPECT_GT(checked_right, checked / 2);
}

bool sameStream(const TrackStream& a, const TrackStream& b) {
  if (a.frames.size() != b.frames.size()) return false;
  for (std::size_t i = 0; i < a.frames.size(); ++i) {
    const auto& x = a.frames[i].observations;
    const auto& y = b.frames[i].observations;
    if (a.frames[i].t_ns != b.frames[i].t_ns || x.size() != y.size()) return false;
    for (std::size_t k = 0; k < x.size(); ++k) {
      if (x[k].track_id != y[k].track_id || x[k].uv0 != y[k].uv0 ||
          x[k].has_right != y[k].has_right || x[k].uv1 != y[k].uv1 ||
          x[k].landmark_id != y[k].landmark_id || x[k].is_outlier != y[k].is_outlier) {
        return false;
      }
    }
  }
  return true;
}

TEST_P(TrackerScenario, SameSeedSameStreamOtherSeedDiffers) {
  const TrackStream a = simulate(options_.tracker, 5);
  EXPECT_TRUE(sameStream(a, simulate(options_.tracker, 5)));
  EXPECT_FALSE(sameStream(a, simulate(options_.tracker, 6)));
  EXPECT_EQ(a.seed, 5u);
}

TEST_P(TrackerScenario, NoiseAndOutlierStatistics) {
  TrackerOptions tracker = options_.tracker;
  tracker.outlier_probability = 0.05;  // more outliers: tighter share estimate
  const TrackStream stream = simulate(tracker, 2);
  double sum2 = 0;
  std::size_t inliers = 0, outliers = 0, total = 0;
  for (const TrackFrame& frame : stream.frames) {
    const TrajectorySample body = trajectory_->evaluate(frame.t_ns);
    for (const StereoObservation& obs : frame.observations) {
      ++total;
      double z = 0;
      const Eigen::Vector2d r = obs.uv0 - projectTrue(body, sequence_.calib.cam0,
                                                      stream.landmarks_w[obs.landmark_id], &z);
      if (obs.is_outlier) {
        ++outliers;
        // Displaced by 5–20 px (plus noise), unless clamped at the image edge.
        const bool clamped = obs.uv0.x() == 0 || obs.uv0.y() == 0 ||
                             obs.uv0.x() == sequence_.calib.cam0.width - 1 ||
                             obs.uv0.y() == sequence_.calib.cam0.height - 1;
        if (!clamped) {
          EXPECT_GT(r.norm(), tracker.outlier_min_px - 6 * tracker.pixel_sigma);
          EXPECT_LT(r.norm(), tracker.outlier_max_px + 6 * tracker.pixel_sigma);
        }
      } else {
        sum2 += r.squaredNorm();
        ++inliers;
      }
    }
  }
  // Per-coordinate σ estimate from 2·inliers values: relative std error 1/√(4 inliers).
  const double sigma = std::sqrt(sum2 / (2.0 * inliers));
  EXPECT_NEAR(sigma, tracker.pixel_sigma, 5 * tracker.pixel_sigma / std::sqrt(4.0 * inliers));
  const double share = static_cast<double>(outliers) / total;
  const double p = tracker.outlier_probability;
  EXPECT_NEAR(share, p, 5 * std::sqrt(p * (1 - p) / total));
}

TEST_P(TrackerScenario, DetectionFillsFreeCellsOnlyAndTracksAreConsistent) {
  TrackerOptions tracker = options_.tracker;
  tracker.noise = false;
  tracker.outliers = false;
  const TrackStream stream = simulate(tracker, 3);
  const double cell = tracker.grid_cell_px;
  std::set<int64_t> previous, ended;
  std::map<int64_t, int64_t> landmark_of;
  for (const TrackFrame& frame : stream.frames) {
    std::set<std::pair<int, int>> occupied, detected;
    std::set<int64_t> current, landmarks;
    for (const StereoObservation& obs : frame.observations) {
      const std::pair<int, int> c{static_cast<int>(obs.uv0.x() / cell),
                                  static_cast<int>(obs.uv0.y() / cell)};
      ASSERT_TRUE(current.insert(obs.track_id).second);
      ASSERT_TRUE(landmarks.insert(obs.landmark_id).second) << "landmark tracked twice";
      ASSERT_EQ(ended.count(obs.track_id), 0u) << "a track came back";
      const auto [it, fresh] = landmark_of.emplace(obs.track_id, obs.landmark_id);
      ASSERT_EQ(it->second, obs.landmark_id);
      if (previous.count(obs.track_id)) {
        occupied.insert(c);
      } else {
        ASSERT_TRUE(fresh);
        // A new track only in a cell without a continued track, and one per cell.
        ASSERT_EQ(occupied.count(c), 0u);
        ASSERT_TRUE(detected.insert(c).second);
      }
    }
    for (const int64_t id : previous) {
      if (!current.count(id)) ended.insert(id);
    }
    previous = current;
  }
}

TEST_P(TrackerScenario, TrackStatisticsTargets) {
  const TrackStatistics s = trackStatistics(simulate(options_.tracker, 4));
  EXPECT_GE(s.features_per_frame.mean, 100);
  EXPECT_LE(s.features_per_frame.mean, 250);
  EXPECT_GE(s.track_length.median, GetParam().indoor ? 5 : 3);
  EXPECT_GT(s.stereo_share, 0.8);
  EXPECT_GT(s.features_per_frame.min, 0);
}

INSTANTIATE_TEST_SUITE_P(Sim, TrackerScenario,
                         ::testing::Values(Scenario{"EurocIndoorLoop", "euroc/MH_01_easy", true},
                                           Scenario{"KittiStreetDrive", "kitti/10", false}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(TrackStatistics, Distribution) {
  const Distribution d = distributionOf({5, 1, 3, 2, 4, 10, 6, 7, 8, 9});
  EXPECT_DOUBLE_EQ(d.mean, 5.5);
  EXPECT_DOUBLE_EQ(d.median, 5.5);
  EXPECT_DOUBLE_EQ(d.p90, 9);
  EXPECT_DOUBLE_EQ(d.min, 1);
  EXPECT_DOUBLE_EQ(d.max, 10);
}

// The real EuRoC MH_01 trajectory (GT spline), first 300 frames: the docs/design.md §5 targets.
TEST(SimulateSequence, EurocMh01PrefixStatistics) {
  const Sequence seq = loadSequence("euroc/MH_01_easy", LoadOptions{false});
  const TrajectorySpline spline = TrajectorySpline::fromSequence(seq);
  SimulationOptions options = defaultSimulationOptions(seq, 1);
  options.tracker.max_frames = 300;
  const TrackStream stream = simulateSequence(seq, spline, options);
  EXPECT_EQ(stream.sequence, "euroc/MH_01_easy");
  ASSERT_EQ(stream.frames.size(), 300u);
  const auto [first, last] = framesWithinTrajectory(seq);
  (void)last;
  EXPECT_GE(stream.frames.front().t_ns, seq.cam_t_ns[first]);
  const TrackStatistics s = trackStatistics(stream);
  EXPECT_GE(s.features_per_frame.mean, 100);
  EXPECT_LE(s.features_per_frame.mean, 250);
  EXPECT_GE(s.track_length.median, 5);
}

TEST(SimulateSequence, RefusesSequenceWithoutTrajectory) {
  const Sequence seq = loadSequence("tumvi/corridor2", LoadOptions{false});
  const test::IndoorLoop loop(1.0);
  EXPECT_THROW(simulateSequence(seq, loop, defaultSimulationOptions(seq)), InputError);
}

}  // namespace
}  // namespace marglab
