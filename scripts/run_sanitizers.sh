#!/usr/bin/env bash
# The sanitizer and fuzzing stage of CI (.ci/run runs it after scripts/run_tests.sh; docs/design.md,
# "Sanitizers and fuzzing"). One clang build in build-san with ASan + UBSan and libFuzzer's coverage
# instrumentation serves both:
#   1. the reduced test suite under the sanitizers (the test modules below, minus the long
#      end-to-end tests), which must be clean;
#   2. a short bounded run of every fuzz target (fuzz/README.md) from its seed corpus, seed 1, but
#      fuzz_track_hdf5, the campaign through libhdf5 (MARGLAB_FUZZ_LIBHDF5 below).
# Setup (scripts/setup.sh) must have run: it installs clang, libFuzzer and llvm-symbolizer.
#   MARGLAB_SAN_BUILD_DIR   build folder (default: build-san)
#   MARGLAB_JOBS            parallel build and test jobs (default: number of cores)
#   MARGLAB_FUZZ_RUNS       inputs per fuzz target (default: 2000: the same inputs on every machine)
#   MARGLAB_FUZZ_SECONDS    a cap in seconds per fuzz target (default: 300; 0 skips the fuzzers)
#   MARGLAB_FUZZ_LIBHDF5    inputs of the campaign through libhdf5 (fuzz_track_hdf5) run after
#                           the others (default: 0, none). It gates nothing: what it finds inside
#                           libhdf5 is contained by the trust boundary (core/io/hdf5_trust.h) and
#                           is triaged by hand (fuzz/README.md, "The campaign through libhdf5")
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR="${MARGLAB_SAN_BUILD_DIR:-build-san}"
JOBS="${MARGLAB_JOBS:-$(nproc)}"
FUZZ_SECONDS="${MARGLAB_FUZZ_SECONDS:-300}"
export MARGLAB_FUZZ_RUNS="${MARGLAB_FUZZ_RUNS:-2000}"
# The test modules (test/<module>) built here: the parsers, I/O, data, config, linear algebra and
# estimator tests. Not cli, frontend, bench, ceres_marg: they run the same library code end to end
# through the CLI, OpenCV or Ceres, at many times the cost.
MODULES="common;data;diagnostics;estimator;experiment;geometry;imu;io;linalg;pipeline;sim"
# Long tests left out: the end-to-end sweep and Slurm tests (the CLI, Python or Slurm in a loop)
# and the whole-run estimator tests (Vo*, Vio*, NfrStrategy, DenseStrategyTest, with or without a
# parameter prefix such as F64/: a sliding window over hundreds of
# frames, 30-150x slower under ASan at -O1 than in the release build — minutes each). The library
# code they run is the one the unit tests, the parsers and the fuzzers exercise; one whole run
# stays in (REPRESENTATIVE): the NFR Schur-complement run, where UBSan once found a null reference
# bound inside Eigen for a landmark without a pose block. Also left out: profile_provenance, which
# checks the shipped simulator profiles against the front-end's statistics on the shipped frames,
# digit for digit. Those digits are the release (GCC) build's; the front-end of this clang -O1
# build tracks the frames slightly differently (a stereo share moves in its third digit, 0.1232 →
# 0.12134): another build's floating point, as the same-build reproducibility rule allows. It also
# runs the CLI through Python, like the end-to-end tests above.
LONG_TESTS="^([A-Za-z0-9]+/)?(SlurmSweep|SlurmOutcome|SweepEndToEnd|SweepKill|StrategyTables|NfrStrategy|DenseStrategyTest|Vio[A-Z][A-Za-z]*|Vo[A-Z][A-Za-z]*)\\.|^profile_provenance$"
REPRESENTATIVE="^NfrStrategy\\.EveryKeyframeEventIsSparsifiedSchurF64$"

# ccache keys on paths relative to the checkout, so a clean clone elsewhere (CI) hits the cache.
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$(pwd)}"
# -O1: a usable speed with exact stack traces; asserts (Eigen's bounds checks) stay on.
CC=clang CXX=clang++ cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
  -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
  -DMARGLAB_FUZZ=ON -DMARGLAB_BENCHMARKS=OFF -DMARGLAB_TEST_MODULES="$MODULES"
cmake --build "$BUILD_DIR" -j "$JOBS"

# Every report stops the program with a stack trace; leaks are reported at exit (suppressions for
# the uninstrumented system libraries: fuzz/lsan.supp, each entry says why).
export ASAN_OPTIONS="halt_on_error=1:abort_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1:allocator_may_return_null=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
export LSAN_OPTIONS="suppressions=$(pwd)/fuzz/lsan.supp:print_suppressions=0"

echo "sanitizers: the reduced test suite under ASan + UBSan"
ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$JOBS" -E "$LONG_TESTS"
ctest --test-dir "$BUILD_DIR" --output-on-failure -R "$REPRESENTATIVE"

if [ "$FUZZ_SECONDS" -gt 0 ]; then
  bash fuzz/run_fuzzers.sh "$BUILD_DIR" "$FUZZ_SECONDS"
fi
# In fork mode, going on after each finding: its seeds include inputs libhdf5 does not survive.
if [ "${MARGLAB_FUZZ_LIBHDF5:-0}" -gt 0 ]; then
  MARGLAB_FUZZ_RUNS="$MARGLAB_FUZZ_LIBHDF5" MARGLAB_FUZZ_OUT="$BUILD_DIR/fuzz-libhdf5" \
    MARGLAB_FUZZ_FLAGS="-fork=1 -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1" \
    bash fuzz/run_fuzzers.sh "$BUILD_DIR" "$FUZZ_SECONDS" track_hdf5 ||
    echo "fuzz_track_hdf5 (non-gating): inputs to triage in $BUILD_DIR/fuzz-libhdf5/artifacts"
fi
