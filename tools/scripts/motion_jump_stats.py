#!/usr/bin/env python3
"""The motion-consistency check's ratio (core/pipeline/motion_check.h) on legitimate motion.

For the ground truth of every shipped sequence at its camera times, and for the estimate of any
results files given, the largest ratio

    jump_k = |p_k - p_hat_k| / max(median of the last 10 steps, floor),

p_hat_k the constant-velocity prediction from frames k-1 and k-2. The run fails above
failure.max_motion_jump (3); this shows how far legitimate motion stays below it.

    /usr/bin/python3 tools/scripts/motion_jump_stats.py [RUN.h5 ...] [--floor 0.05]
"""
import argparse
import glob
import gzip
import os
import sys

import numpy as np

RECENT_STEPS = 10
DATASETS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "datasets")


def jumps(t, p, floor):
    steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
    out = []
    for k in range(2, len(p)):
        predicted = p[k - 1] + (p[k - 1] - p[k - 2]) * (t[k] - t[k - 1]) / (t[k - 1] - t[k - 2])
        recent = np.median(steps[max(0, k - 1 - RECENT_STEPS):k - 1])
        out.append(np.linalg.norm(p[k] - predicted) / max(recent, floor))
    return np.array(out)


def kitti(folder):
    poses = np.loadtxt(gzip.open(os.path.join(folder, "poses.txt.gz")))
    return np.loadtxt(gzip.open(os.path.join(folder, "times.txt.gz"))), poses[:, [3, 7, 11]]


def asl(folder):
    gt = np.loadtxt(gzip.open(os.path.join(folder, "gt_tum.txt.gz")))
    t = np.loadtxt(gzip.open(os.path.join(folder, "cam0_timestamps_ns.txt.gz"))) * 1e-9
    t = t[(t >= gt[0, 0]) & (t <= gt[-1, 0])]
    return t, np.stack([np.interp(t, gt[:, 0], gt[:, i]) for i in (1, 2, 3)], 1)


def ground_truths():
    for folder in sorted(glob.glob(os.path.join(DATASETS, "kitti", "[0-9][0-9]"))):
        yield "kitti/" + os.path.basename(folder), kitti(folder)
    for kind in ("euroc", "tumvi"):
        for folder in sorted(glob.glob(os.path.join(DATASETS, kind, "*"))):
            if os.path.exists(os.path.join(folder, "gt_tum.txt.gz")) and os.path.exists(
                    os.path.join(folder, "cam0_timestamps_ns.txt.gz")):
                yield kind + "/" + os.path.basename(folder), asl(folder)


def estimate(path):
    import h5py
    with h5py.File(path, "r") as f:
        return np.array(f["frames"]["t_ns"]) * 1e-9, np.array(f["frames"]["p_est"])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="*", help="results files (their /frames p_est)")
    parser.add_argument("--floor", type=float, default=0.05, help="failure.motion_floor_m")
    args = parser.parse_args()
    sources = [(name, tp) for name, tp in ground_truths()]
    sources += [(path, estimate(path)) for path in args.runs]
    print("| source | frames | largest jump | frame | 99.9 % |")
    print("|---|---:|---:|---:|---:|")
    for name, (t, p) in sources:
        j = jumps(t, p, args.floor)
        if len(j) == 0:
            continue
        print("| %s | %d | %.2f | %d | %.2f |" % (name, len(p), j.max(), int(np.argmax(j)) + 2,
                                                 np.quantile(j, 0.999)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
