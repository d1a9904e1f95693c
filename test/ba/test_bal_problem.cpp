// The BAL loader (core/ba/bal_problem.h): the shipped problems, plain and bzip2, their initial
// costs against the published values, and malformed files → InputError naming file and line.
#include <bzlib.h>
#include <gtest/gtest.h>

#include <fstream>

#include "common/temp_dir.h"
#include "core/ba/ba_state.h"
#include "core/ba/bal_problem.h"
#include "core/common/error.h"
#include "core/common/source_dir.h"

namespace marglab {
namespace {

std::string shipped(const std::string& name) {
  return std::string(sourceDir()) + "/datasets/bal/" + name;
}

double initialCost(const BalProblem& problem) {
  return evaluateCost(problem.observations, BalState<double>::fromProblem(problem), RobustLoss{})
      .cost;
}

// Published in the tests of JuliaSmoothOptimizers/BundleAdjustmentModels.jl (to 11 digits, so
// 1e-9 relative checks our cost to the digits given); the cost is a sum of 3·10⁴ positive terms
// in double, rounding ≈ 1e-12 relative.
TEST(BalProblem, InitialCostsEqualThePublishedOnes) {
  const BalProblem ladybug = loadBalProblem(shipped("ladybug-problem-49-7776-pre.txt.bz2"));
  EXPECT_EQ(ladybug.name, "ladybug-problem-49-7776-pre");
  EXPECT_EQ(ladybug.numCameras(), 49);
  EXPECT_EQ(ladybug.numPoints(), 7776);
  EXPECT_EQ(ladybug.numObservations(), 31843);
  EXPECT_NEAR(initialCost(ladybug) / 8.5091246068e+05, 1.0, 1e-9);
  const BalProblem trafalgar = loadBalProblem(shipped("trafalgar-problem-21-11315-pre.txt.bz2"));
  EXPECT_EQ(trafalgar.numObservations(), 36455);
  EXPECT_NEAR(initialCost(trafalgar) / 4.4132393144e+06, 1.0, 1e-9);
}

TEST(BalProblem, PointsBehindTheirCameraAreCountedAsRootbaDoes) {
  const BalProblem ladybug = loadBalProblem(shipped("ladybug-problem-49-7776-pre.txt.bz2"));
  const CostSummary cost =
      evaluateCost(ladybug.observations, BalState<double>::fromProblem(ladybug), RobustLoss{});
  EXPECT_EQ(cost.num_behind, 31);  // rootba: "num valid 31812" of 31843
  EXPECT_TRUE(cost.finite);
}

TEST(BalProblem, SmallProblemsLoadWithTheirCosts) {
  const BalProblem dubrovnik = loadBalProblem(shipped("dubrovnik-3-7-pre.txt"));
  EXPECT_EQ(dubrovnik.numCameras(), 3);
  EXPECT_EQ(dubrovnik.numObservations(), 19);
  EXPECT_NEAR(initialCost(dubrovnik) / 2.7642199844e+03, 1.0, 1e-9);
  const BalProblem shrink =
      loadBalProblem(shipped("ladybug-problem-49-7776-pre-shrink-1800.txt.bz2"));
  EXPECT_EQ(shrink.numPoints(), 1800);
  EXPECT_NEAR(initialCost(shrink) / 2.3451979857e+05, 1.0, 1e-9);
}

class BalProblemFiles : public test::TempDirTest {
 protected:
  std::string write(const std::string& name, const std::string& bytes) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << bytes;
    return path;
  }
  // The InputError of loading `text`, checked to name the file and `line`.
  void expectError(const std::string& text, int line, const std::string& fragment) {
    const std::string path = write("bad.txt", text);
    try {
      loadBalProblem(path);
      ADD_FAILURE() << "no error for:\n" << text;
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), path);
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_NE(e.detail().find(fragment), std::string::npos) << e.what();
    }
  }
};

// One camera, one point, two observations: the smallest well-formed file.
const char* kHeader = "1 1 2\n";
const char* kObservations = "0 0 1.0 2.0\n0 0 3.0 4.0\n";
const char* kCamera = "0\n0\n0\n0\n0\n0\n500\n0\n0\n";
const char* kPoint = "1\n2\n-5\n";

TEST_F(BalProblemFiles, AWellFormedFileLoads) {
  const BalProblem p = loadBalProblem(
      write("ok.txt", std::string(kHeader) + kObservations + kCamera + kPoint + "\n\n"));
  EXPECT_EQ(p.observations[1].z, (Vec<double, 2>(3.0, 4.0)));
  EXPECT_EQ(p.cameras[0][6], 500.0);
  EXPECT_EQ(p.points[0], Vec3<double>(1, 2, -5));
}

TEST_F(BalProblemFiles, MalformedFilesNameTheLine) {
  const std::string obs(kObservations), cam(kCamera), pt(kPoint);
  expectError("1 1 x\n" + obs + cam + pt, 1, "the number of observations");
  expectError("1 0 2\n" + obs + cam + pt, 1, "positive the number of points");
  expectError("1 1 2\n0 0 1.0 2.0\n0 1 3.0 4.0\n" + cam + pt, 3, "point index in [0, 1)");
  expectError("1 1 2\n0 0 1.0 2.0\n-1 0 3.0 4.0\n" + cam + pt, 3, "camera index");
  expectError(std::string(kHeader) + obs + "0\n0\n0\n0\n0\n0\nnan\n0\n0\n" + pt, 10,
              "finite a camera parameter");
  expectError(std::string(kHeader) + obs + cam + "1\n2e\n-5\n", 14, "a point coordinate");
  expectError(std::string(kHeader) + obs + cam + pt + "7\n", 16, "end of the file");
  expectError(std::string(kHeader) + obs + cam + "1\n2\n", 15, "got the end of the file");
  expectError("1 1 200000000\n", 1, "numbers after the counts");
}

TEST_F(BalProblemFiles, MissingAndCorruptFilesAreInputErrors) {
  EXPECT_THROW(loadBalProblem((dir_ / "absent.txt").string()), InputError);
  const std::string corrupt = write("corrupt.txt.bz2", "BZh91AY&SYnot really bzip2");
  try {
    loadBalProblem(corrupt);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), corrupt);
    EXPECT_NE(e.detail().find("bzip2"), std::string::npos) << e.what();
  }
}

TEST_F(BalProblemFiles, Bzip2AndPlainLoadTheSame) {
  std::string text = std::string(kHeader) + kObservations + kCamera + kPoint;
  std::string compressed(text.size() + 1024, '\0');
  unsigned size = static_cast<unsigned>(compressed.size());
  ASSERT_EQ(BZ2_bzBuffToBuffCompress(compressed.data(), &size, text.data(),
                                     static_cast<unsigned>(text.size()), 9, 0, 0),
            BZ_OK);
  compressed.resize(size);
  const BalProblem plain = loadBalProblem(write("p.txt", text));
  // Two streams back to back (pbzip2) decompress to the text twice: a file too long.
  EXPECT_THROW(loadBalProblem(write("twice.txt.bz2", compressed + compressed)), InputError);
  const BalProblem bz = loadBalProblem(write("p.txt.bz2", compressed));
  EXPECT_EQ(bz.name, "p");
  EXPECT_EQ(bz.cameras[0], plain.cameras[0]);
  EXPECT_EQ(bz.points[0], plain.points[0]);
}

}  // namespace
}  // namespace marglab
