#!/usr/bin/env bash
# Quick start (a): set up, build, and run the main job on the shipped data.
set -euo pipefail
cd "$(dirname "$0")/.."
# The main job needs only the CLI: the tests and benchmarks are built by scripts/run_tests.sh.
MARGLAB_BUILD_TARGETS=marglab_cli bash scripts/setup.sh
BUILD_DIR="${MARGLAB_BUILD_DIR:-build}"
# The main job: the quick reproduction of the paper (sweep, tables, figures, the executed notebooks
# and the report checked in headless Chromium; < 10 min on 2 cores). It ends by printing where the
# tables (results/quick/tables), figures, notebooks and report (notebooks-out/quick) are.
code=0
"$BUILD_DIR/bin/marglab" reproduce --quick --jobs "${MARGLAB_JOBS:-0}" || code=$?
echo
echo "report:    $(pwd)/notebooks-out/quick/report.html"
echo "notebooks: $(pwd)/notebooks-out/quick/sweep.html, precision.html, runs/<id>.html (+ .ipynb)"
exit "$code"
