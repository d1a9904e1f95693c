#!/usr/bin/env bash
# The online stereo offset on rendered KITTI 00 frames (issue #40 §5): 50 frames rendered with the
# exact calibration, and the same frames whose calib.txt moves the right camera's cx by -0.6 px
# (the front-end and the estimator load the wrong camera; the pixels are exact). Runs with and
# without the window variable, the prior's σ at 0.1 / 1 / 10 px, and the offset the
# `datasets stereo-bias` verb measures on the same frames with ground truth and with the run's own
# poses. Writes OUT/ (runs, verb fragments) and prints the recovery table.
# Usage: experiments/stereo_offset_online.sh MARGLAB OUT   (from the repository root)
set -euo pipefail
if [ $# -ne 2 ]; then sed -n 2,9p "$0"; exit 2; fi
bin=$(realpath "$1")
mkdir -p "$2"
out=$(realpath "$2")
root=$(pwd)
on="estimator.estimate_right_cx_offset=true"
"$bin" datasets render --dataset kitti/00 --frames 50 --seed 4 -o "$out/r00" > "$out/render.log"
python3 tools/scripts/kitti_clip.py --dataset "$out/r00/sequences/00" --frames 0:49 \
  --right-cx-shift -0.6 -o "$out/r00c" >> "$out/render.log"
run() {  # name dataset variant [--set ...]
  local name=$1 data=$2 variant=$3
  shift 3
  "$bin" run --dataset "$data" --variant "$variant" "$@" -o "$out/$name.h5" > "$out/$name.log"
}
for v in ns-qr-sqrt-f64 ns-qr-sqrt-f32; do
  run "exact_off_$v" "$out/r00" "$v"
  run "exact_online_$v" "$out/r00" "$v" --set "$on"
  run "shifted_off_$v" "$out/r00c" "$v"
  run "shifted_online_$v" "$out/r00c" "$v" --set "$on"
done
for s in 0.1 10; do
  run "shifted_online_sigma${s}_ns-qr-sqrt-f64" "$out/r00c" ns-qr-sqrt-f64 --set "$on" \
    --set "estimator.right_cx_offset_prior_px=$s"
done
for frames in 0:9 0:29 0:49; do
  "$bin" datasets stereo-bias --dataset "$out/r00c" --frames "$frames" \
    -o "$out/gt_frames${frames/:/-}.toml" > /dev/null
  "$bin" datasets stereo-bias --dataset "$out/r00c" --frames "$frames" \
    --poses "$out/shifted_off_ns-qr-sqrt-f64.tum" -o "$out/vo_frames${frames/:/-}.toml" > /dev/null
done
grep -H "right_cx_shift_px =" "$out"/gt_*.toml "$out"/vo_*.toml
cd "$root"
python3 tools/scripts/stereo_offset_table.py --poses "$out/r00c/poses.txt" --reference 0.6 \
  "$out"/exact_*.h5 "$out"/shifted_*.h5
