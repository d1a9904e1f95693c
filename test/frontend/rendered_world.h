#pragma once
// Scoring the front-end (core/frontend/optical_flow.h) on frames rendered from the simulated world
// (core/frontend/world_render.h), where the true raw pixel of every sprite is known.
//
// Truth of a track. A new track is associated with the sprite whose centre c lies within 5 px of
// its raw keypoint x, if no other sprite lies within 20 px (a keypoint on two overlapping sprites
// follows either: ambiguous, not scored); its offset δ = x − c is kept. In a later frame its true
// raw pixel is c' + δ (the sprite looks the same everywhere, world_render.h), undistorted into the
// estimator's pinhole image like the keypoint; the tracking error is the distance between the two
// pinhole pixels. A track whose point left the view is not scored there.
// Wrong forward steps. A forward LK step (before the checks) is wrong when it moved the keypoint by
// more than kOutlierPx away from the true motion of its sprite (or the point left the view); a
// wrong step the checks let through corrupts the track, whose later pixels are not scored (they
// count as the surviving outlier instead).
// Disparity error. For a scored observation with a right match: (u0 − u1) − (ū0 − ū1) in the
// pinhole image, ū the true pixels — signed, since a disparity bias δ scales every stereo depth by
// d / (d + δ) and with it a VO trajectory (results/real_kitti06/README.md).
// Continued share. Per frame k ≥ 1, n_tracked(k) / n_features(k − 1) (issue #29's measure), its
// median over the frames.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/data/types.h"
#include "core/frontend/optical_flow.h"
#include "core/frontend/world_render.h"
#include "core/sim/trajectory_spline.h"
#include "core/sim/world.h"

namespace marglab::test {

constexpr double kOutlierPx = 1.0;  // a forward track further from the truth is wrong

inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

constexpr std::size_t kNoLandmark = static_cast<std::size_t>(-1);

struct TrackTruth {
  std::size_t landmark = kNoLandmark;  // none: the detection was not on a single sprite
  Eigen::Vector2d offset = Eigen::Vector2d::Zero();  // detected raw pixel − sprite centre
  bool corrupted = false;  // an outlier the checks let through: its later pixels are not scored
};

struct Measured {
  std::vector<double> track_error, stereo_error;  // [px] in the pinhole image
  std::vector<double> disparity_error;            // [px] signed, pinhole image (header)
  std::vector<double> raw_error;  // [px] left tracking error in the raw image (where LK works)
  std::vector<double> continued;  // per frame k ≥ 1: n_tracked(k) / n_features(k − 1)
  int wrong_forward = 0, wrong_removed = 0, surviving_outliers = 0, associated = 0;
};

// One frame's forward candidates and observations against the truth.
inline void score(const CameraModel<double>& cam0, const CameraModel<double>& cam1,
                  const RenderedFrame& previous, const RenderedFrame& image,
                  const TrackFrame& frame, const std::vector<Eigen::Vector2d>& raw_left,
                  const std::vector<FlowCandidate>& flow,
                  std::unordered_map<int64_t, TrackTruth>* truth, Measured* m) {
  for (const FlowCandidate& c : flow) {
    const auto t = truth->find(c.track_id);
    if (!c.lk_ok || t == truth->end() || t->second.landmark == kNoLandmark || t->second.corrupted) {
      continue;
    }
    const auto centre = image.centre0.find(t->second.landmark);
    const auto before = previous.centre0.find(t->second.landmark);
    const bool wrong =
        centre == image.centre0.end() || before == previous.centre0.end() ||
        (Eigen::Vector2d(c.u - c.u_prev, c.v - c.v_prev) - (centre->second - before->second))
                .norm() > kOutlierPx;
    if (!wrong) continue;
    ++m->wrong_forward;
    if (c.kept) {
      t->second.corrupted = true;
      ++m->surviving_outliers;
    } else {
      ++m->wrong_removed;
    }
  }
  for (std::size_t i = 0; i < frame.observations.size(); ++i) {
    const StereoObservation& obs = frame.observations[i];
    auto t = truth->find(obs.track_id);
    if (t == truth->end()) {
      TrackTruth& entry = (*truth)[obs.track_id];
      int near = 0;
      for (const auto& [l, c] : image.centre0) {
        const double d = (raw_left[i] - c).norm();
        if (d < 20.0) ++near;
        if (d < 5.0) entry = {l, raw_left[i] - c};
      }
      if (near != 1) entry = {};
      m->associated += entry.landmark != kNoLandmark;
      continue;
    }
    if (t->second.landmark == kNoLandmark || t->second.corrupted) continue;
    const auto c0 = image.centre0.find(t->second.landmark);
    if (c0 == image.centre0.end()) continue;  // left the view: scored by the forward check
    m->raw_error.push_back((raw_left[i] - (c0->second + t->second.offset)).norm());
    Eigen::Vector2d expected0, expected1;
    ASSERT_TRUE(cam0.undistortPixel(c0->second + t->second.offset, &expected0));
    m->track_error.push_back((obs.uv0 - expected0).norm());
    const auto c1 = image.centre1.find(t->second.landmark);
    if (obs.has_right && c1 != image.centre1.end() &&
        cam1.undistortPixel(c1->second + t->second.offset, &expected1)) {
      m->stereo_error.push_back((obs.uv1 - expected1).norm());
      m->disparity_error.push_back((obs.uv0.x() - obs.uv1.x()) - (expected0.x() - expected1.x()));
    }
  }
}

// What the front-end is run on: the sequence (calibration, front-end options), the trajectory,
// the world and the frame times.
struct RenderedScene {
  const Sequence* sequence;
  const TrajectorySpline* spline;
  const World* world;
  RenderOptions render;
  std::vector<int64_t> t_ns;
};

// Renders the scene, runs the front-end on it and scores it; prints one line under `label`.
inline Measured trackRendered(const std::string& label, const RenderedScene& scene,
                              std::vector<RenderedFrame>* images, std::vector<TrackFrame>* frames) {
  const StereoCalib& calib = scene.sequence->calib;
  const WorldRenderer renderer(*scene.world, calib, scene.render);
  for (std::size_t k = 0; k < scene.t_ns.size(); ++k) {
    images->push_back(renderer.render(scene.spline->evaluate(scene.t_ns[k]), static_cast<int>(k)));
  }
  StereoFrontend frontend(calib, defaultFrontendOptions(*scene.sequence), "test");
  const auto cam0 = cameraModelFromCalib<double>(calib.cam0, "test");
  const auto cam1 = cameraModelFromCalib<double>(calib.cam1, "test");
  std::unordered_map<int64_t, TrackTruth> truth;
  Measured m;
  int previous_features = 0;
  for (std::size_t k = 0; k < scene.t_ns.size(); ++k) {
    std::vector<FlowCandidate> flow;
    FrontendFrameStats stats;
    const RenderedFrame& image = (*images)[k];
    frames->push_back(frontend.process(scene.t_ns[k], image.left, image.right, &stats, &flow));
    if (k > 0 && previous_features > 0) {
      m.continued.push_back(static_cast<double>(stats.n_tracked) / previous_features);
    }
    previous_features = stats.n_features;
    score(cam0, cam1, (*images)[k > 0 ? k - 1 : 0], image, frames->back(), frontend.lastRawLeft(),
          flow, &truth, &m);
  }
  std::printf(
      "%s: %zu tracked observations, error median %.4f px, p95 %.4f px (raw image: median %.4f "
      "px, p95 %.4f px); stereo median %.4f px (%zu), disparity error median %+.4f px; continued "
      "median %.1f %%; wrong forward "
      "steps %d, removed %.1f %%; %d associated, %d outliers survived\n",
      label.c_str(), m.track_error.size(), percentile(m.track_error, 0.5),
      percentile(m.track_error, 0.95), percentile(m.raw_error, 0.5), percentile(m.raw_error, 0.95),
      percentile(m.stereo_error, 0.5), m.stereo_error.size(), percentile(m.disparity_error, 0.5),
      100.0 * percentile(m.continued, 0.5), m.wrong_forward,
      100.0 * m.wrong_removed / std::max(m.wrong_forward, 1), m.associated, m.surviving_outliers);
  return m;
}

}  // namespace marglab::test
