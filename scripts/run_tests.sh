#!/usr/bin/env bash
# Quick start (b): set up, build, and run the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
BUILD_DIR="${MARGLAB_BUILD_DIR:-build}"
ctest --test-dir "$BUILD_DIR" --output-on-failure -j "${MARGLAB_JOBS:-$(nproc)}"
