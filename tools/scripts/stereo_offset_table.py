#!/usr/bin/env python3
"""The online stereo offset's recovery table (issue #40 §5) from marglab results files.

Usage: stereo_offset_table.py [--poses POSES.txt] [--reference PX] RUN.h5 [RUN.h5 ...]

One markdown row per run: the offset /frames/right_cx_offset_px after frames 1, 2, 5, 10, 20, 30
and the last (the frame index counts from 0), the frame from which it stays within 0.05 px of its
last value ("settles"), the ATE (/summary ate_rmse) and, with --poses (KITTI poses.txt of the
same frames), the drift and path length of tools/scripts/kitti_drift.py on the run's .tum beside
it. --reference: the offset to compare with (e.g. the verb's ground-truth measurement); the
table's last column is then the last value minus it. A run without the variable shows "—".
Needs numpy, h5py.
"""
import argparse
import os
import subprocess
import sys

import h5py
import numpy as np

FRAMES = [1, 2, 5, 10, 20, 30]
SETTLE_PX = 0.05


def settle_frame(c):
    """First index from which |c - c[-1]| <= SETTLE_PX holds to the end."""
    within = np.abs(c - c[-1]) <= SETTLE_PX
    k = len(c)
    while k > 0 and within[k - 1]:
        k -= 1
    return k


def drift(tum, poses):
    script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "kitti_drift.py")
    out = subprocess.run([sys.executable, script, tum, poses], capture_output=True, text=True,
                         check=True).stdout.strip().splitlines()[-1].split()
    return f"{out[1]} %", out[4]  # "drift X % path Y final ..."


def row(path, poses, reference):
    with h5py.File(path, "r") as f:
        c = f["frames/right_cx_offset_px"][()] if "right_cx_offset_px" in f["frames"] else None
        ate = float(f["summary"].attrs["ate_rmse"])
    name = os.path.basename(path)[:-3]
    cells = [name]
    if c is None or np.all(np.isnan(c)):
        cells += ["—"] * (len(FRAMES) + 2)
    else:
        cells += [f"{c[k]:+.3f}" if k < len(c) else "" for k in FRAMES]
        cells += [f"{c[-1]:+.3f} ({len(c) - 1})", str(settle_frame(c))]
    cells.append(f"{ate:.4f}")
    if poses:
        cells += list(drift(path[:-3] + ".tum", poses))
    if reference is not None:
        cells.append("—" if c is None or np.all(np.isnan(c)) else f"{c[-1] - reference:+.3f}")
    return "| " + " | ".join(cells) + " |"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+")
    parser.add_argument("--poses")
    parser.add_argument("--reference", type=float)
    args = parser.parse_args()
    head = ["run"] + [f"c after {k}" for k in FRAMES] + ["c last (frame)", "settles at",
                                                        "ATE [m]"]
    if args.poses:
        head += ["drift", "path / GT"]
    if args.reference is not None:
        head.append(f"last − {args.reference:+.4f}")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for path in args.runs:
        print(row(path, args.poses, args.reference))
    return 0


if __name__ == "__main__":
    sys.exit(main())
