#!/usr/bin/env bash
# Re-measures results/bal (docs/bundle_adjustment.md): every shipped BAL problem x every `marglab
# ba` solver under rootba's protocol (50 iterations, Huber 1 px, scale normalized to 100,
# perturbation 0.01, seed 38401), rootba's tutorial run (ladybug-49, 20 iterations, normalized,
# no perturbation, no robust loss) for every solver, and the Ceres peers with 2 threads; then the
# table of tools/scripts/bal_profile.py and the figures of tools/scripts/bal_plot.py.
#   usage: tools/scripts/bal_measure.sh [OUT_FOLDER (results/bal)] [MARGLAB (build/bin/marglab)]
# One run at a time, one thread each (unless stated): times are wall-clock on a quiet machine.
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="${1:-results/bal}"
B="${2:-build/bin/marglab}"
SOLVERS=(ns-f32 ns-f64 sc-f32 sc-f64 ceres-implicit ceres-explicit ceres-sparse)
mkdir -p "$OUT/protocol" "$OUT/tutorial" "$OUT/threads2"
for p in ladybug-problem-49-7776-pre ladybug-problem-49-7776-pre-shrink-1800 \
         trafalgar-problem-21-11315-pre; do
  for s in "${SOLVERS[@]}"; do
    "$B" ba --problem "datasets/bal/$p.txt.bz2" --solver "$s" --iterations 50 --huber 1 \
      --normalize 100 --perturb 0.01 --seed 38401 -o "$OUT/protocol/${p}_$s.h5" > /dev/null 2>&1
  done
  for s in ceres-implicit ceres-explicit ceres-sparse; do
    "$B" ba --problem "datasets/bal/$p.txt.bz2" --solver "$s" --iterations 50 --huber 1 \
      --normalize 100 --perturb 0.01 --seed 38401 --threads 2 \
      -o "$OUT/threads2/${p}_$s.h5" > /dev/null 2>&1
  done
done
for s in "${SOLVERS[@]}"; do
  "$B" ba --problem datasets/bal/ladybug-problem-49-7776-pre.txt.bz2 --solver "$s" \
    --iterations 20 --normalize 100 -o "$OUT/tutorial/ladybug_$s.h5" > /dev/null 2>&1
done
for group in protocol tutorial threads2; do
  /usr/bin/python3 tools/scripts/bal_profile.py "$OUT/$group" > "$OUT/$group.md"
done
/usr/bin/python3 tools/scripts/bal_plot.py "$OUT/protocol"
