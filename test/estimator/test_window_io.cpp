// Window files (core/estimator/window_io.h) that the fuzzer (fuzz/fuzz_window) found to break the
// reader: each is kept in fuzz/corpus/window/ and must be rejected with an InputError, without
// undefined behaviour or a huge allocation (the sanitizer build checks both).

#include <gtest/gtest.h>

#include <string>

#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/estimator/window_io.h"

namespace marglab {
namespace {

std::string fuzzInput(const std::string& name) {
  return std::string(sourceDir()) + "/fuzz/corpus/window/" + name;
}

std::string readError(const std::string& path) {
  try {
    readWindow(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

// "landmarks 99999999" in a 300-byte file used to resize the landmark vector to 6.4 GB first.
TEST(WindowFileFuzzRegression, CountBeyondTheFileIsRejectedBeforeAllocating) {
  EXPECT_NE(readError(fuzzInput("crash-landmark-count-beyond-the-file")).find("bad count 99999999"),
            std::string::npos);
}

// A 2^32 × 2^32 prior matrix overflowed rows * cols (undefined behaviour) in the size check.
TEST(WindowFileFuzzRegression, MatrixSizeThatOverflowsIsRejected) {
  EXPECT_NE(readError(fuzzInput("crash-matrix-size-overflow")).find("bad matrix size"),
            std::string::npos);
}

// A 2 × 2 matrix where the prior's residual vector belongs failed Eigen's resize assertion.
TEST(WindowFileFuzzRegression, PriorVectorWithTwoColumnsIsRejected) {
  EXPECT_NE(readError(fuzzInput("crash-prior-vector-with-two-columns")).find("expected a vector"),
            std::string::npos);
}

// The checks reject only what the file cannot hold: a shipped window still reads.
TEST(WindowFileFuzzRegression, ShippedWindowStillReads) {
  const WindowSnapshot w = readWindow(std::string(sourceDir()) +
                                      "/datasets/windows/kitti-00_ns-qr-sqrt-f32_000100.win.gz");
  EXPECT_EQ(w.frames.size(), 8u);
  EXPECT_EQ(w.landmarks.size(), 172u);
  EXPECT_EQ(w.prior_blocks.size(), 7u);
}

}  // namespace
}  // namespace marglab
