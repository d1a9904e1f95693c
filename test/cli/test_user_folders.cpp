// Sweeps over a user's dataset folders (issue 38 items 4-6): `tables` keys a run by the kind and
// sequence its results file records, and keeps two folders recording one name apart (with a
// warning) instead of collapsing them into one cell; a folder holding part of a sequence (a clip)
// is labelled with its frame count, never "all", and shows no whole-sequence paper value, nor does
// a shipped sequence's run cut short by `frames`;
// `plot` draws the figures of such a sweep (it knew only shipped names).

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
#include "core/common/source_dir.h"
#include "core/data/sequence.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;
using test::quote;
using test::runCli;

class UserFoldersTest : public test::TempDirTest {
 protected:
  // The first `frames` frames of the shipped KITTI 06, as a user's folder `name`/06.
  fs::path clip(const std::string& name, int frames) {
    const fs::path folder = dir_ / name / "06";
    fs::create_directories(folder);
    const fs::path shipped = fs::path(datasetsRoot()) / "kitti" / "06";
    fs::copy_file(shipped / "calib.txt", folder / "calib.txt");
    for (const char* file : {"times.txt", "poses.txt"}) {
      const auto r =
          test::runShell("zcat " + quote(shipped / (std::string(file) + ".gz")) + " | head -" +
                         std::to_string(frames) + " > " + quote(folder / file));
      EXPECT_EQ(r.exit_code, 0) << r.output;
    }
    return folder;
  }

  // A sweep of `variants` on the folders (relative to dir_); returns the sweep folder.
  fs::path sweep(const std::string& datasets, const std::string& variants) {
    std::ofstream(dir_ / "sweep.toml") << "name = \"user\"\n[[group]]\nname = \"g\"\ndatasets = ["
                                       << datasets << "]\nvariants = [" << variants << "]\n";
    const auto r = runCli("sweep " + quote(dir_ / "sweep.toml") + " --out " + quote(dir_ / "out"));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return dir_ / "out";
  }
};

TEST_F(UserFoldersTest, TablesKeepCollidingFoldersApartAndLabelClips) {
  clip("a", 51);
  clip("b", 74);
  const fs::path out = sweep("\"a/06\", \"b/06\"", "\"ns-qr-sqrt-f64\"");
  const auto tables = runCli("tables " + quote(out) + " --print");
  ASSERT_EQ(tables.exit_code, 0) << tables.output;
  const std::string a = (dir_ / "a" / "06").string(), b = (dir_ / "b" / "06").string();
  EXPECT_NE(tables.output.find("warning: kitti/06: runs on 2 datasets record this name"),
            std::string::npos)
      << tables.output;
  // One row each, labelled with its clip's frames, without the paper's whole-sequence 2.61.
  EXPECT_NE(tables.output.find("| kitti/06 (" + a + ") | 51 |"), std::string::npos)
      << tables.output;
  EXPECT_NE(tables.output.find("| kitti/06 (" + b + ") | 74 |"), std::string::npos)
      << tables.output;
  EXPECT_EQ(tables.output.find("2.61"), std::string::npos) << tables.output;
}

TEST_F(UserFoldersTest, AClipIsLabelledWithItsFramesNotAsTheWholeSequence) {
  clip("c", 51);
  const fs::path out = sweep("\"c/06\"", "\"ns-qr-sqrt-f64\"");
  const auto tables = runCli("tables " + quote(out) + " --print");
  ASSERT_EQ(tables.exit_code, 0) << tables.output;
  EXPECT_NE(tables.output.find("| kitti06 | 51 |"), std::string::npos) << tables.output;
  EXPECT_EQ(tables.output.find("| all |"), std::string::npos) << tables.output;
  EXPECT_EQ(tables.output.find("2.61"), std::string::npos) << tables.output;
}

// Issue 38 item 6, the strict reading: a run of a shipped sequence cut short by `frames` = N is a
// part of it too. The paper's whole-sequence value (Table 2, kitti04: 1.22) stands beside the whole
// 271 frames only, and a `frames` at or above the length is the whole sequence.
TEST_F(UserFoldersTest, APaperValueStandsBesideAWholeSequenceRunOnly) {
  const auto table2 = [this](const std::string& frames) {
    std::ofstream(dir_ / "k.toml") << "name = \"k\"\n[[group]]\nname = \"g\"\n"
                                   << "datasets = [\"kitti/04\"]\nvariants = [\"ns-qr-sqrt-f64\"]\n"
                                   << frames;
    fs::remove_all(dir_ / "k");
    const auto r = runCli("sweep " + quote(dir_ / "k.toml") + " --out " + quote(dir_ / "k"));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    const auto tables = runCli("tables " + quote(dir_ / "k") + " --print");
    EXPECT_EQ(tables.exit_code, 0) << tables.output;
    const std::string& out = tables.output;
    const std::size_t at = out.find("| kitti04 |", out.find("Table 2"));
    return at == std::string::npos ? out : out.substr(at, out.find('\n', at) - at);
  };
  const std::string part = table2("frames = 50\n");
  EXPECT_EQ(part.rfind("| kitti04 | 50 |", 0), 0u) << part;
  EXPECT_EQ(part.find("1.22"), std::string::npos) << part;
  const std::string whole = table2("");
  EXPECT_EQ(whole.rfind("| kitti04 | all |", 0), 0u) << whole;
  EXPECT_NE(whole.find("1.22"), std::string::npos) << whole;
  const std::string beyond = table2("frames = 300\n");
  EXPECT_EQ(beyond.rfind("| kitti04 | 300 |", 0), 0u) << beyond;
  EXPECT_NE(beyond.find("1.22"), std::string::npos) << beyond;
}

TEST_F(UserFoldersTest, PlotDrawsTheFiguresOfAUserFolderSweep) {
  if (std::system("/usr/bin/python3 -c 'import matplotlib, h5py, numpy' > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "no /usr/bin/python3 with matplotlib, h5py and numpy";
  }
  clip("c", 51);
  const fs::path out = sweep("\"c/06\"", "\"headline\"");
  const auto plot = runCli("plot " + quote(out) + " -o " + quote(dir_ / "figures"));
  EXPECT_EQ(plot.exit_code, 0) << plot.output;
  EXPECT_TRUE(fs::is_regular_file(dir_ / "figures" / "fig7_trajectory_kitti-06.png"))
      << plot.output;
}

// Issue 38 (low): tools/scripts/kitti_clip.py did not read the KITTI download's layout (poses in
// dataset/poses/NN.txt), accepted a NaN shift and printed a traceback for an output under a file.
TEST_F(UserFoldersTest, KittiClipReadsTheDownloadLayoutAndRefusesBadArguments) {
  if (std::system("/usr/bin/python3 -c 'import numpy' > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "no /usr/bin/python3 with numpy";
  }
  const fs::path shipped = fs::path(datasetsRoot()) / "kitti" / "06_images";
  const fs::path seq = dir_ / "K" / "dataset" / "sequences" / "06";
  const fs::path poses = dir_ / "K" / "dataset" / "poses";
  fs::create_directories(poses);
  for (const char* cam : {"image_0", "image_1"}) {
    fs::create_directories(seq / cam);
    for (const char* image : {"000000.png", "000001.png", "000002.png"}) {
      fs::copy_file(shipped / cam / image, seq / cam / image);
    }
  }
  fs::copy_file(shipped / "calib.txt", seq / "calib.txt");
  const auto head = [&](const char* from, const fs::path& to) {
    EXPECT_EQ(test::runShell("head -3 " + quote(shipped / from) + " > " + quote(to)).exit_code, 0);
  };
  head("times.txt", seq / "times.txt");
  head("poses.txt", poses / "06.txt");
  std::ofstream(dir_ / "a_file") << "x";
  const std::string clip = "/usr/bin/python3 " +
                           quote(fs::path(sourceDir()) / "tools" / "scripts" / "kitti_clip.py") +
                           " --dataset " + quote(seq) + " --frames 0:2 ";
  const auto ok = test::runShell(clip + "-o " + quote(dir_ / "clip"));
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
  EXPECT_TRUE(fs::is_regular_file(dir_ / "clip" / "poses.txt")) << ok.output;
  const auto nan = test::runShell(clip + "--right-cx-shift nan -o " + quote(dir_ / "nan"));
  EXPECT_EQ(nan.exit_code, 1) << nan.output;
  EXPECT_NE(nan.output.find("expected a finite number"), std::string::npos) << nan.output;
  const auto under = test::runShell(clip + "-o " + quote(dir_ / "a_file" / "out"));
  EXPECT_EQ(under.exit_code, 1) << under.output;
  EXPECT_EQ(under.output.find("Traceback"), std::string::npos) << under.output;
  EXPECT_NE(under.output.find("expected an existing folder"), std::string::npos) << under.output;
}

}  // namespace
}  // namespace marglab
