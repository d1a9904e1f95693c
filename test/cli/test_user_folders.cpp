// Sweeps over a user's dataset folders (issue 38 items 4-6): `tables` keys a run by the kind and
// sequence its results file records, and keeps two folders recording one name apart (with a
// warning) instead of collapsing them into one cell; a folder holding part of a sequence (a clip)
// is labelled with its frame count, never "all", and shows no whole-sequence paper value;
// `plot` draws the figures of such a sweep (it knew only shipped names).

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/cli_runner.h"
#include "common/temp_dir.h"
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
      const auto r = test::runShell("zcat " + quote(shipped / (std::string(file) + ".gz")) +
                                    " | head -" + std::to_string(frames) + " > " +
                                    quote(folder / file));
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

}  // namespace
}  // namespace marglab
