#!/usr/bin/env bash
# Quick start (a): set up, build, and run the main job on the shipped data.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
BUILD_DIR="${MARGLAB_BUILD_DIR:-build}"
"$BUILD_DIR/bin/marglab" verify
