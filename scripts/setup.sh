#!/usr/bin/env bash
# Installs the Debian packages marglab needs (only those missing), then configures and builds
# marglab in ./build (Release). Idempotent: a second run installs nothing and rebuilds incrementally.
#   MARGLAB_BUILD_DIR       build folder (default: build)
#   MARGLAB_JOBS            parallel build jobs (default: number of cores)
#   MARGLAB_BUILD_TARGETS   targets to build, space-separated (default: all; scripts/run_main.sh
#                           builds only marglab_cli, the tests and benchmarks are left for later)
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake pkg-config git ccache  # ccache: repeated clean-clone builds take minutes
  universal-ctags  # tools/scripts/long_functions.py (test long_functions)
  clang-format  # tools/scripts/check_format.sh (test clang_format)
  libeigen3-dev libsuitesparse-dev libceres-dev libcli11-dev libfmt-dev libhdf5-dev zlib1g-dev
  libbz2-dev  # bzip2-compressed BAL problems (core/ba/bal_problem.cpp)
  libgtest-dev libgmock-dev libbenchmark-dev libtomlplusplus-dev libopencv-dev
  libpng-dev libjpeg-dev  # core/frontend/image_file.cpp
  nlohmann-json3-dev  # JSON output (core/massspring, core/bench)
  python3 python3-matplotlib python3-h5py python3-numpy python3-scipy  # scipy: tools/scripts
  python3-opencv  # tools/scripts/kitti_rotation_check.py: an estimate independent of marglab
  python3-pandas jupyter-nbconvert python3-nbclient python3-nbformat python3-ipykernel
  chromium python3-websocket
  slurm-wlm munge  # scripts/slurm_local.sh: a one-node Slurm cluster for `sweep --backend slurm`
  clang libclang-rt-dev llvm  # scripts/run_sanitizers.sh: ASan/UBSan, libFuzzer, llvm-symbolizer
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]})); then
  echo "setup: installing missing Debian packages: ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y --no-install-recommends "${missing[@]}"
else
  echo "setup: all Debian packages present"
fi

BUILD_DIR="${MARGLAB_BUILD_DIR:-build}"
JOBS="${MARGLAB_JOBS:-$(nproc)}"
# ccache keys on paths relative to the checkout, so a clean clone elsewhere (CI) hits the cache.
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$(pwd)}"
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release
targets=()
for t in ${MARGLAB_BUILD_TARGETS:-}; do targets+=(--target "$t"); done
cmake --build "$BUILD_DIR" -j "$JOBS" "${targets[@]}"
