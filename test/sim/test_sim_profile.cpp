// The simulator's realistic profile (core/sim/sim_profile.h): its random variates against their
// distributions (closed forms and numerical integration of the density, tolerances from the
// sample size), the drift walk and the grid fill measured on simulated tracks, the shipped profile
// file and its validation, and the config key.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/frontend/image_folder.h"
#include "core/frontend/track_source.h"
#include "core/pipeline/run_config.h"
#include "core/sim/feature_tracker.h"
#include "core/sim/sim_profile.h"
#include "sim_test_utils.h"

namespace marglab {
namespace {

// P(|T| <= x) for Student-t with nu dof: 2 ∫_0^x f(t) dt by composite Simpson (f from lgamma), an
// independent computation of what SimRandom::studentT samples.
double studentAbsCdf(double nu, double x) {
  const double log_c =
      std::lgamma(0.5 * (nu + 1)) - std::lgamma(0.5 * nu) - 0.5 * std::log(nu * SimRandom::kPi);
  auto f = [&](double t) { return std::exp(log_c - 0.5 * (nu + 1) * std::log1p(t * t / nu)); };
  const int n = 20000;  // even
  const double h = x / n;
  double sum = f(0) + f(x);
  for (int i = 1; i < n; ++i) sum += (i % 2 == 1 ? 4 : 2) * f(i * h);
  return 2 * sum * h / 3;
}

TEST(SimRandomStudentT, AbsCdfMatchesTheDensity) {
  // Closed forms check the integration: Cauchy P(|T| <= 1) = 1/2, t_2: 1/sqrt(3).
  EXPECT_NEAR(studentAbsCdf(1, 1), 0.5, 1e-9);
  EXPECT_NEAR(studentAbsCdf(2, 1), 1 / std::sqrt(3.0), 1e-9);
  const int n = 200000;
  for (const double nu : {1.03, 2.5, 8.0}) {
    SimRandom rng(SimRandom::subSeed(7, static_cast<uint64_t>(nu * 100)));
    std::vector<double> x(n);
    for (double& v : x) v = rng.studentT(nu);
    for (const double q : {0.25, 1.0, 2.0, 5.0}) {
      double inside = 0;
      for (const double v : x) inside += std::abs(v) <= q ? 1 : 0;
      const double p = studentAbsCdf(nu, q);
      // Binomial sampling error of the empirical share, 5 sigma.
      EXPECT_NEAR(inside / n, p, 5 * std::sqrt(p * (1 - p) / n)) << "nu " << nu << " x " << q;
    }
  }
}

TEST(SimRandomGamma, MeanAndVarianceEqualTheShape) {
  const int n = 200000;
  for (const double a : {0.515, 1.26, 4.0}) {
    SimRandom rng(SimRandom::subSeed(3, static_cast<uint64_t>(a * 1000)));
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; ++i) {
      const double g = rng.gamma(a);
      ASSERT_GE(g, 0);
      sum += g;
      sum2 += g * g;
    }
    const double mean = sum / n, var = sum2 / n - mean * mean;
    // Gamma(a, 1): mean a, variance a, fourth central moment 3a² + 6a.
    EXPECT_NEAR(mean, a, 5 * std::sqrt(a / n)) << a;
    EXPECT_NEAR(var, a, 5 * std::sqrt((3 * a * a + 6 * a - a * a) / n)) << a;
  }
}

class RealisticTracks : public ::testing::Test {
 protected:
  void SetUp() override {
    sequence_ = loadSequence("euroc/V1_01_easy", LoadOptions{false});
    trajectory_ = std::make_unique<test::IndoorLoop>(20.0);
    times_ = test::uniformTimes(trajectory_->endTimeNs(), 50'000'000);
    options_ = defaultSimulationOptions(sequence_, 11);
    world_ = makeWorld(*trajectory_, options_.world, options_.seed);
  }
  TrackStream simulate(const TrackerOptions& tracker, uint64_t seed) const {
    return simulateTracks(*trajectory_, sequence_.calib, times_, world_, tracker, seed);
  }
  Eigen::Vector2d truth(const StereoObservation& obs, int64_t t_ns, const TrackStream& s) const {
    Eigen::Matrix3d R_w_c;
    Eigen::Vector3d p_w_c;
    cameraPose(trajectory_->evaluate(t_ns), sequence_.calib.cam0, &R_w_c, &p_w_c);
    const Eigen::Vector3d p_c = R_w_c.transpose() * (s.landmarks_w[obs.landmark_id] - p_w_c);
    const CameraCalib& c = sequence_.calib.cam0;
    return {c.fx * p_c.x() / p_c.z() + c.cx, c.fy * p_c.y() / p_c.z() + c.cy};
  }

  Sequence sequence_;
  std::unique_ptr<TrajectoryFunction> trajectory_;
  std::vector<int64_t> times_;
  SimulationOptions options_;
  World world_;
};

TEST_F(RealisticTracks, DriftIsARandomWalkOfTheGivenStep) {
  TrackerOptions tracker = options_.tracker;
  tracker.noise = false;
  tracker.outliers = false;
  tracker.drift_step_px = 0.2;
  const TrackStream stream = simulate(tracker, 4);
  std::map<int64_t, Eigen::Vector2d> last;  // per track: offset at its previous frame
  double sum2 = 0;
  std::size_t n = 0, first = 0;
  for (const TrackFrame& frame : stream.frames) {
    std::map<int64_t, Eigen::Vector2d> now;
    for (const StereoObservation& obs : frame.observations) {
      const Eigen::Vector2d d = obs.uv0 - truth(obs, frame.t_ns, stream);
      now[obs.track_id] = d;
      const auto it = last.find(obs.track_id);
      if (it == last.end()) {
        ASSERT_LT(d.norm(), 1e-9);  // no offset at detection
        ++first;
      } else {
        sum2 += (d - it->second).squaredNorm();
        n += 2;
      }
    }
    last = std::move(now);
  }
  ASSERT_GT(n, 10000u);
  ASSERT_GT(first, 100u);
  // Increments N(0, step²) per coordinate: the mean square has relative std error sqrt(2/n).
  const double s2 = tracker.drift_step_px * tracker.drift_step_px;
  EXPECT_NEAR(sum2 / n, s2, 5 * s2 * std::sqrt(2.0 / n));
}

TEST_F(RealisticTracks, StudentNoiseAndCellFill) {
  TrackerOptions tracker = options_.tracker;
  tracker.outliers = false;
  tracker.student_nu = 2.5;
  tracker.pixel_sigma = 0.3;
  tracker.cell_fill_probability = 0.6;
  const TrackStream stream = simulate(tracker, 5);
  std::size_t inside = 0, n = 0;
  for (const TrackFrame& frame : stream.frames) {
    for (const StereoObservation& obs : frame.observations) {
      const Eigen::Vector2d r = obs.uv0 - truth(obs, frame.t_ns, stream);
      for (int i = 0; i < 2; ++i) inside += std::abs(r[i]) <= tracker.pixel_sigma ? 1 : 0;
      n += 2;
    }
  }
  const double p = studentAbsCdf(2.5, 1.0);
  EXPECT_NEAR(static_cast<double>(inside) / n, p, 5 * std::sqrt(p * (1 - p) / n));
  // First frame: every free cell with a candidate starts a track with probability 0.6.
  TrackerOptions full = tracker;
  full.cell_fill_probability = 1;
  const double cells = static_cast<double>(simulate(full, 5).frames[0].observations.size());
  const double got = static_cast<double>(stream.frames[0].observations.size());
  EXPECT_NEAR(got, 0.6 * cells, 5 * std::sqrt(cells * 0.6 * 0.4));
}

TEST_F(RealisticTracks, DeterministicForASeed) {
  TrackerOptions tracker = options_.tracker;
  applyRealisticProfile(readRealisticProfile(realisticProfilePath(DatasetKind::kEuroc)), &tracker);
  const TrackStream a = simulate(tracker, 8), b = simulate(tracker, 8), c = simulate(tracker, 9);
  ASSERT_EQ(a.frames.size(), b.frames.size());
  bool same_c = a.frames.size() == c.frames.size();
  for (std::size_t k = 0; k < a.frames.size(); ++k) {
    ASSERT_EQ(a.frames[k].observations.size(), b.frames[k].observations.size());
    for (std::size_t i = 0; i < a.frames[k].observations.size(); ++i) {
      EXPECT_EQ(a.frames[k].observations[i].uv0, b.frames[k].observations[i].uv0);
      EXPECT_EQ(a.frames[k].observations[i].uv1, b.frames[k].observations[i].uv1);
    }
    same_c = same_c && c.frames[k].observations.size() == a.frames[k].observations.size() &&
             (a.frames[k].observations.empty() ||
              c.frames[k].observations[0].uv0 == a.frames[k].observations[0].uv0);
  }
  EXPECT_FALSE(same_c);
}

// Each family's shipped profile reads and lies in its ranges; its values are the calibrated ones
// (results/frontend_stats/frontend_stats.json, results/frontend_stats/kitti06/), not checked here
// against constants.
TEST(RealisticProfileFile, ShippedProfilesRead) {
  for (DatasetKind kind : {DatasetKind::kEuroc, DatasetKind::kKitti}) {
    const RealisticProfile p = readRealisticProfile(realisticProfilePath(kind));
    EXPECT_GT(p.nu, 0) << datasetKindName(kind);
    EXPECT_GT(p.scale_px, 0) << datasetKindName(kind);
    EXPECT_LE(p.outlier_min_px, p.outlier_max_px) << datasetKindName(kind);
    EXPECT_GT(p.cell_fill_probability, 0) << datasetKindName(kind);
  }
}

// KITTI runs take the profile measured on KITTI frames, EuRoC and TUM-VI the EuRoC one; the two
// files are distinct calibrations (the moving KITTI clip measures track loss, the static EuRoC one
// cannot and keeps the ideal 0.03).
TEST(RealisticProfileFile, FamilySelectsItsFile) {
  namespace fs = std::filesystem;
  EXPECT_EQ(fs::path(realisticProfilePath(DatasetKind::kKitti)).filename(), "realistic_kitti.toml");
  EXPECT_EQ(fs::path(realisticProfilePath(DatasetKind::kEuroc)).filename(), "realistic_euroc.toml");
  EXPECT_EQ(fs::path(realisticProfilePath(DatasetKind::kTumvi)).filename(), "realistic_euroc.toml");
  EXPECT_EQ(fs::path(realisticProfilePath(DatasetKind::kKitti)).parent_path(),
            fs::path(datasetsRoot()) / "sim_profiles");
  const RealisticProfile kitti = readRealisticProfile(realisticProfilePath(DatasetKind::kKitti));
  const RealisticProfile euroc = readRealisticProfile(realisticProfilePath(DatasetKind::kEuroc));
  EXPECT_NE(kitti.scale_px, euroc.scale_px);
  EXPECT_NE(kitti.loss_probability, euroc.loss_probability);
}

// `realistic-motion` reads the EuRoC / TUM-VI file calibrated on moving keyframes, KITTI's moving
// one as `realistic` does; `realistic` itself still reads the static EuRoC file.
TEST(RealisticProfileFile, MotionProfileSelectsTheKeyframeFile) {
  namespace fs = std::filesystem;
  const SimProfile motion = SimProfile::kRealisticMotion;
  EXPECT_EQ(fs::path(realisticProfilePath(DatasetKind::kEuroc, motion)).filename(),
            "realistic_euroc_motion.toml");
  EXPECT_EQ(fs::path(realisticProfilePath(DatasetKind::kTumvi, motion)).filename(),
            "realistic_euroc_motion.toml");
  EXPECT_EQ(fs::path(realisticProfilePath(DatasetKind::kKitti, motion)).filename(),
            "realistic_kitti.toml");
  SimProfile parsed = SimProfile::kIdeal;
  ASSERT_TRUE(parseSimProfile("realistic-motion", &parsed));
  EXPECT_EQ(parsed, motion);
  const RealisticProfile moving =
      readRealisticProfile(realisticProfilePath(DatasetKind::kEuroc, motion));
  const RealisticProfile still = readRealisticProfile(realisticProfilePath(DatasetKind::kEuroc));
  EXPECT_NE(moving.scale_px, still.scale_px);
  EXPECT_NE(moving.stereo_failure_probability, still.stereo_failure_probability);
}

// The simulation a run uses applies its family's file and records which one in the results file's
// provenance (sim_profile), so a results file names the profile it was simulated with.
TEST(RealisticProfileFile, SimulationRecordsItsFamilysFile) {
  const SimProfile still = SimProfile::kRealistic, motion = SimProfile::kRealisticMotion;
  for (const auto& [dataset, profile, file] :
       std::vector<std::tuple<std::string, SimProfile, std::string>>{
           {"kitti/04", still, "realistic_kitti.toml"},
           {"euroc/V1_01_easy", still, "realistic_euroc.toml"},
           {"tumvi/room1", still, "realistic_euroc.toml"},
           {"euroc/V1_01_easy", motion, "realistic_euroc_motion.toml"},
           {"tumvi/room1", motion, "realistic_euroc_motion.toml"}}) {
    TrackSourceOptions options;
    options.dataset = dataset;
    options.frontend = FrontendKind::kSimulated;
    options.max_frames = 3;
    options.sim_profile = profile;
    const TrackSource source = obtainTracks(options, loadImageSequence(dataset));
    std::string recorded;
    for (const auto& [key, value] : source.provenance) {
      if (key == "sim_profile") recorded = value;
    }
    EXPECT_EQ(recorded.rfind(std::string(toString(profile)) + " (", 0), 0u)
        << dataset << ": " << recorded;
    EXPECT_NE(recorded.find("sim_profiles/" + file + ")"), std::string::npos)
        << dataset << ": " << recorded;
  }
}

std::string writeProfile(const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() /
                    ("marglab_profile_" + std::to_string(::getpid()) + ".toml");
  std::ofstream(path) << text;
  return path.string();
}

const char* kValid =
    "[noise]\nnu = 2.5\nscale_px = 0.2\n[drift]\nstep_px = 0.01\n"
    "[outliers]\nprobability = 0.01\nmin_px = 5\nmax_px = 20\n"
    "[tracking]\nloss_probability = 0.03\nstereo_failure_probability = 0.5\n"
    "cell_fill_probability = 1\n";

TEST(RealisticProfileFile, ErrorsNameFileLineAndRange) {
  const RealisticProfile ok = readRealisticProfile(writeProfile(kValid));
  EXPECT_EQ(ok.nu, 2.5);
  EXPECT_EQ(ok.stereo_failure_probability, 0.5);
  auto message = [](const std::string& text) {
    const std::string path = writeProfile(text);
    try {
      readRealisticProfile(path);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  std::string text = kValid;
  EXPECT_NE(message(text.replace(text.find("nu = 2.5"), 8, "nu = -1.0")).find(":2: noise.nu"),
            std::string::npos);
  text = kValid;
  EXPECT_NE(message(text + "extra = 1\n").find("unknown key tracking.extra"), std::string::npos);
  text = kValid;
  EXPECT_NE(message(text.replace(text.find("min_px = 5"), 10, "min_px = 50")).find("min <= max"),
            std::string::npos);
  text = kValid;
  EXPECT_NE(message(text.erase(text.find("step_px"), 15)).find("missing drift.step_px"),
            std::string::npos);
  EXPECT_NE(message("[noise\n").find(".toml:1"), std::string::npos);
  EXPECT_THROW(readRealisticProfile("/nonexistent/profile.toml"), InputError);
}

TEST(SimProfileConfig, KeyParsesAndRejectsUnknownNames) {
  RunConfig config;
  EXPECT_EQ(config.sim_profile, SimProfile::kIdeal);
  config.loadTomlString("[sim]\nprofile = \"realistic\"\n", "c.toml");
  EXPECT_EQ(config.sim_profile, SimProfile::kRealistic);
  EXPECT_NE(config.toToml().find("realistic"), std::string::npos);
  try {
    config.loadTomlString("[sim]\nprofile = \"noisy\"\n", "c.toml");
    FAIL() << "accepted an unknown profile";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("c.toml:2"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("\"ideal\", \"realistic\" or \"realistic-motion\""),
              std::string::npos)
        << e.what();
  }
}

// [sim] grid_cell_px, loss_probability, stereo_failure_probability replace single tracker
// settings on top of the profile (−1: keep), and are range-checked with the file and line.
TEST(SimProfileConfig, OverridesReplaceSingleTrackerSettings) {
  RunConfig config;
  EXPECT_FALSE(config.sim_overrides.any());
  TrackerOptions tracker;
  const TrackerOptions untouched = tracker;
  applySimOverrides(config.sim_overrides, &tracker);
  EXPECT_EQ(tracker.grid_cell_px, untouched.grid_cell_px);
  EXPECT_EQ(tracker.loss_probability, untouched.loss_probability);
  EXPECT_EQ(tracker.stereo_failure_probability, untouched.stereo_failure_probability);
  config.loadTomlString("[sim]\ngrid_cell_px = 20\nloss_probability = 0\n", "c.toml");
  EXPECT_TRUE(config.sim_overrides.any());
  applySimOverrides(config.sim_overrides, &tracker);
  EXPECT_EQ(tracker.grid_cell_px, 20.0);
  EXPECT_EQ(tracker.loss_probability, 0.0);
  EXPECT_EQ(tracker.stereo_failure_probability, untouched.stereo_failure_probability);
  WorldOptions world = defaultWorldOptions(DatasetKind::kKitti);
  const WorldOptions street = world;
  applySimOverrides(config.sim_overrides, &world);
  EXPECT_EQ(world.facade_offset_max, street.facade_offset_max);
  config.loadTomlString("[sim]\nfacade_offset_scale = 2\n", "c.toml");
  applySimOverrides(config.sim_overrides, &world);
  EXPECT_EQ(world.facade_offset_min, 2 * street.facade_offset_min);
  EXPECT_EQ(world.facade_offset_max, 2 * street.facade_offset_max);
  for (const char* bad :
       {"[sim]\ngrid_cell_px = 4\n", "[sim]\nloss_probability = 1.5\n",
        "[sim]\nstereo_failure_probability = -0.5\n", "[sim]\nfacade_offset_scale = 0\n"}) {
    RunConfig probe;
    try {
      probe.loadTomlString(bad, "c.toml");
      FAIL() << "accepted " << bad;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("c.toml:2"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace marglab
