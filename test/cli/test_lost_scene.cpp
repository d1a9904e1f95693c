// The tracking monitor's consistency rule end to end (core/pipeline/tracking_monitor.h): tracks
// that go on but no longer fit any pose. From frame 30 on, half of every frame's observations of a
// simulated KITTI 00 track file are swapped among themselves (wrong associations, as a front-end
// that confuses repeated texture makes them): the frames keep hundreds of observations of the
// window's landmarks, so the starvation rule cannot see it, while the estimate leaves the road
// (the ground-truth bound of 100 m only fires ~16 frames later). The run must fail as "tracking"
// within max_tracking_loss_frames of the corruption; the untouched file runs ok.

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <random>
#include <string>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/data/sequence.h"
#include "core/io/results_file.h"
#include "core/sim/track_io.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::quote;
using test::runCli;

class LostScene : public test::TempDirTest {};

// Swaps the measurements of half of each frame's observations from `first` on, in random pairs.
void scrambleHalf(TrackStream* stream, size_t first) {
  std::mt19937 rng(7);
  for (size_t k = first; k < stream->frames.size(); ++k) {
    std::vector<StereoObservation>& obs = stream->frames[k].observations;
    std::vector<size_t> order(obs.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), rng);
    for (size_t i = 0; i + 1 < order.size() / 2; i += 2) {
      StereoObservation& a = obs[order[i]];
      StereoObservation& b = obs[order[i + 1]];
      std::swap(a.uv0, b.uv0);
      std::swap(a.uv1, b.uv1);
      std::swap(a.has_right, b.has_right);
    }
  }
}

TEST_F(LostScene, WrongAssociationsFailAsTracking) {
  const fs::path clean = dir_ / "k00.h5", wrong = dir_ / "k00_wrong.h5";
  ASSERT_EQ(runCli("datasets simulate --dataset kitti/00 --frames 60 -o " + quote(clean)).exit_code,
            0);
  TrackStream stream = readTrackFile(clean.string());
  scrambleHalf(&stream, 30);
  writeTrackFile(wrong.string(), stream);

  const std::string run = "run --dataset kitti/00 --variant ns-qr-sqrt-f64 --no-diagnostics";
  const auto ok = runCli(run + " --tracks " + quote(clean) + " -o " + quote(dir_ / "ok.h5"));
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
  const auto lost = runCli(run + " --tracks " + quote(wrong) + " -o " + quote(dir_ / "lost.h5"));
  EXPECT_EQ(lost.exit_code, 1) << lost.output;
  EXPECT_NE(lost.output.find("(tracking): tracking lost: 3 frame(s) in a row in which more than "
                             "30 % of the observations"),
            std::string::npos)
      << lost.output;
  const ResultsReader reader((dir_ / "lost.h5").string());
  EXPECT_EQ(reader.info().status, "failed");
  EXPECT_EQ(reader.info().failure_kind, "tracking");
  EXPECT_GE(reader.info().failure_frame, 30);
  EXPECT_LE(reader.info().failure_frame, 34);
}

// The motion-consistency check (core/pipeline/motion_check.h, issue #38): the shipped KITTI 06
// frames with frames 25-30 shuffled (25, 27, 28, 30, 29, 26: the images' order, not their times)
// kept every track consistent with some pose and ran ok with 5 times the ATE. The estimate now
// jumps against its constant-velocity prediction, and the run fails as "tracking" in the shuffled
// stretch; the frames in order, and the shuffled ones with the check off, run ok.
TEST_F(LostScene, FramesOutOfOrderFailAsTracking) {
  const fs::path shipped = fs::path(datasetsRoot()) / "kitti" / "06_images";
  const auto copy = [&](const std::string& name, const std::vector<int>& order) {
    const fs::path folder = dir_ / name / "06";
    for (const char* camera : {"image_0", "image_1"}) {
      fs::create_directories(folder / camera);
      for (int k = 0; fs::exists(shipped / camera / fmt::format("{:06d}.png", k)); ++k) {
        const int source = k >= 25 && k <= 30 ? order[static_cast<size_t>(k - 25)] : k;
        fs::create_symlink(shipped / camera / fmt::format("{:06d}.png", source),
                           folder / camera / fmt::format("{:06d}.png", k));
      }
    }
    for (const char* file : {"calib.txt", "times.txt", "poses.txt"}) {
      fs::copy_file(shipped / file, folder / file);
    }
    return folder;
  };
  const std::string run = "run --variant ns-qr-sqrt-f64 --frontend images --no-diagnostics";
  const fs::path in_order = copy("in_order", {25, 26, 27, 28, 29, 30});
  const fs::path shuffled = copy("shuffled", {25, 27, 28, 30, 29, 26});
  const auto ok = runCli(run + " --dataset " + quote(in_order) + " -o " + quote(dir_ / "ok.h5"));
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
  const auto jumped =
      runCli(run + " --dataset " + quote(shuffled) + " -o " + quote(dir_ / "jumped.h5"));
  EXPECT_EQ(jumped.exit_code, 1) << jumped.output;
  EXPECT_NE(jumped.output.find("(tracking): motion inconsistent at frame "), std::string::npos)
      << jumped.output;
  const ResultsReader reader((dir_ / "jumped.h5").string());
  EXPECT_EQ(reader.info().failure_kind, "tracking");
  EXPECT_GE(reader.info().failure_frame, 26);
  EXPECT_LE(reader.info().failure_frame, 32);
  const auto off = runCli(run + " --set failure.max_motion_jump=0 --dataset " + quote(shuffled) +
                          " -o " + quote(dir_ / "off.h5"));
  EXPECT_EQ(off.exit_code, 0) << off.output;
}

}  // namespace
}  // namespace marglab
