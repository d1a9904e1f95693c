// Window capture and replay: a window captured by `marglab run --dump-windows` (through
// runSequence) and read back from its file rebuilds a window on which the estimator's optimizer
// reproduces the captured step bit for bit (same build), for VO and VIO, square-root and Hessian
// priors, f32 and f64; the file format round-trips exactly and rejects damaged files.

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/bench/window_replay.h"
#include "core/common/error.h"
#include "core/estimator/window_io.h"
#include "core/pipeline/run.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;

fs::path tempDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("marglab_test_window_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Runs `frames` frames and captures the window of frame `capture`.
WindowSnapshot capture(const std::string& dataset, const std::string& variant, int frames,
                       int capture, const fs::path& dir) {
  RunSpec options;
  options.dataset = dataset;
  options.variant = Variant::parse(variant);
  options.max_frames = frames;
  options.config.diagnostics.enabled = false;
  options.output = (dir / "run.h5").string();
  options.dump_windows = {capture};
  options.dump_dir = dir.string();
  const RunOutcome outcome = runSequence(options);
  EXPECT_EQ(outcome.status, RunStatus::kOk);
  const fs::path file = dir / windowFileName(dataset, variant, capture);
  EXPECT_TRUE(fs::exists(file)) << file;
  return readWindow(file.string());
}

struct Case {
  const char* dataset;
  const char* variant;
  int frames;
  int capture;
};

class WindowReplay : public ::testing::TestWithParam<Case> {};

TEST_P(WindowReplay, ReplayReproducesTheCapturedStepBitForBit) {
  const Case c = GetParam();
  const std::string name = std::string(c.variant) + "_" + std::to_string(c.capture) +
                           (std::string(c.dataset).find("kitti") == 0 ? "_vo" : "_vio");
  const fs::path dir = tempDir(name);
  const WindowSnapshot w = capture(c.dataset, c.variant, c.frames, c.capture, dir);
  EXPECT_EQ(w.variant, c.variant);
  EXPECT_EQ(w.frame_index, c.capture);
  ASSERT_TRUE(w.after.present);
  ASSERT_GT(w.landmarks.size(), 20u);
  ASSERT_GE(w.after.lm_iterations, 1);
  EXPECT_EQ(w.vio, std::string(c.dataset).find("euroc") == 0);
  if (w.vio) {
    EXPECT_FALSE(w.imu_links.empty());
  }
  EXPECT_FALSE(w.prior_blocks.empty());

  const ReplayResult replay = replayWindow(w);
  ASSERT_TRUE(replay.result.status.ok()) << replay.result.status.toString();
  EXPECT_EQ(compareSteps(w.after, replay.step), "");
  // A different precision is a different step: the comparison can fail.
  Variant other = Variant::parse(c.variant);
  other.precision = other.precision == Precision::kF32 ? Precision::kF64 : Precision::kF32;
  const ReplayResult other_replay = replayWindow(w, other);
  ASSERT_TRUE(other_replay.result.status.ok());
  EXPECT_NE(compareSteps(w.after, other_replay.step), "");
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Windows, WindowReplay,
                         ::testing::Values(Case{"euroc/MH_01_easy", "ns-qr-sqrt-f32", 46, 45},
                                           Case{"euroc/MH_01_easy", "sc-sc-sq-f64", 46, 45},
                                           Case{"kitti/00", "ns-qr-sqrt-f64", 14, 13},
                                           Case{"kitti/00", "sc-sc-sq-f32", 14, 13}),
                         [](const auto& info) {
                           std::string s = std::string(info.param.dataset).substr(0, 5) + "_" +
                                           info.param.variant;
                           for (char& ch : s) {
                             if (ch == '-' || ch == '/') ch = '_';
                           }
                           return s;
                         });

TEST(WindowFile, RoundTripsExactlyAndRejectsDamage) {
  const fs::path dir = tempDir("roundtrip");
  const WindowSnapshot w = capture("euroc/MH_01_easy", "ns-qr-sqrt-f32", 21, 20, dir);
  // Written again, plain text this time, and read back: the same bytes once more.
  const fs::path plain = dir / "again.win";
  writeWindow(w, plain.string());
  const WindowSnapshot again = readWindow(plain.string());
  const fs::path plain2 = dir / "again2.win";
  writeWindow(again, plain2.string());
  std::ifstream a(plain), b(plain2);
  const std::string sa((std::istreambuf_iterator<char>(a)), {}),
      sb((std::istreambuf_iterator<char>(b)), {});
  EXPECT_EQ(sa, sb);
  EXPECT_EQ(compareSteps(w.after, again.after), "");
  // The snapshot of a restored estimator is the window itself.
  auto restored = SlidingWindowEstimator<float>::fromSnapshot(w, Variant::parse(w.variant));
  WindowSnapshot s = restored.snapshot();
  s.dataset = w.dataset;
  s.frame_index = w.frame_index;
  s.after = w.after;
  const fs::path plain3 = dir / "restored.win";
  writeWindow(s, plain3.string());
  std::ifstream c(plain3);
  const std::string sc((std::istreambuf_iterator<char>(c)), {});
  EXPECT_EQ(sa, sc);
  // Truncated.
  const fs::path cut = dir / "cut.win";
  std::ofstream(cut) << sa.substr(0, sa.size() / 2);
  EXPECT_THROW(readWindow(cut.string()), InputError);
  // A word where a number belongs.
  std::string bad = sa;
  bad.replace(bad.find("failed_solves 0"), 15, "failed_solves x");
  const fs::path badf = dir / "bad.win";
  std::ofstream(badf) << bad;
  EXPECT_THROW(readWindow(badf.string()), InputError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace marglab
