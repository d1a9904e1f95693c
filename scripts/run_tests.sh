#!/usr/bin/env bash
# Quick start (b): set up, build, and run the whole test suite — with a one-node Slurm cluster up
# for the tests of `sweep --backend slurm`, as .ci/run has it: a cluster that already answers
# (.ci/run's, a real one) is used as it is; otherwise scripts/slurm_local.sh starts one here and
# stops it when the tests end. Where it cannot start (not root, no slurm-wlm) those six tests skip,
# saying why. MARGLAB_NO_SLURM=1 leaves Slurm alone.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if [ "${MARGLAB_NO_SLURM:-0}" != 1 ] && ! sinfo -h >/dev/null 2>&1; then
  if bash scripts/slurm_local.sh start; then
    trap 'bash scripts/slurm_local.sh stop' EXIT
  else
    echo "run_tests: the one-node Slurm cluster did not start; its tests will skip"
  fi
fi
BUILD_DIR="${MARGLAB_BUILD_DIR:-build}"
ctest --test-dir "$BUILD_DIR" --output-on-failure -j "${MARGLAB_JOBS:-$(nproc)}"
