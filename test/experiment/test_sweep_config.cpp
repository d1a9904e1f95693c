// Sweep validation of config values (docs/design.md §8–9, issue #18 item 5): each value is checked
// against its key's range where it is written, and the merged config of every run (config_file,
// [group.config], the override) against the relations between keys — before any run starts.

#include <gtest/gtest.h>

#include <string>

#include "core/common/error.h"
#include "core/experiment/sweep_def.h"

namespace marglab::experiment {
namespace {

const char* const kHead =
    "name = \"bad\"\n[[group]]\nname = \"g\"\ndatasets = [\"kitti/10\"]\n"
    "variants = [\"ns-qr-sqrt-f32\"]\n";  // lines 1-5

void expectRejected(const std::string& text, int line, const std::string& message) {
  try {
    parseSweep(text, "sweep.toml", "/nonexistent");
    FAIL() << "accepted:\n" << text;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "sweep.toml");
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
  }
}

TEST(SweepConfigValues, OutOfRangeValueNamesItsLine) {
  expectRejected(std::string(kHead) + "[group.config]\nlm = { max_iterations = 1e12 }\n", 7,
                 "config: lm.max_iterations = 1000000000000: expected an integer in [1, 1000]");
  expectRejected(std::string(kHead) + "[group.config]\nkeyframes = { connected_ratio = 5 }\n", 7,
                 "keyframes.connected_ratio = 5");
  expectRejected(std::string(kHead) + "[[group.override]]\nname = \"o\"\n" +
                     "config = { residuals = { huber_px = 0 } }\n",
                 8, "residuals.huber_px = 0");
}

TEST(SweepConfigValues, RelationOfTheMergedConfigNamesTheOverride) {
  // Each value is in range, and so is the group with the first override; the second override's
  // λ_init falls below the group's λ_min.
  expectRejected(std::string(kHead) +
                     "[group.config]\nlm = { lambda_min = 1e-3, lambda_init = 1e-2 }\n" +
                     "[[group.override]]\nname = \"ok\"\n" + "[[group.override]]\nname = \"o\"\n" +
                     "config = { lm = { lambda_init = 1e-4 } }\n",
                 10, "group 'g', override 'o': config: lm.lambda_min = 0.001");
  // Without overrides: the group's line.
  expectRejected(std::string(kHead) + "[group.config]\nlm = { lambda_min = 10, lambda_max = 1 }\n",
                 2, "group 'g': config: lm.lambda_min = 10");
  // Two relations at once: both are reported.
  expectRejected(std::string(kHead) +
                     "[group.config]\nlm = { lambda_min = 10, lambda_max = 1 }\n"
                     "marginalization = { nfr_rigid_deflation = true }\n",
                 2, "; also: marginalization.nfr_rigid_deflation = true");
  // The same keys in a valid order pass.
  EXPECT_NO_THROW(parseSweep(std::string(kHead) + "[group.config]\nlm = { lambda_min = 1e-5 }\n",
                             "sweep.toml", "/nonexistent"));
}

}  // namespace
}  // namespace marglab::experiment
