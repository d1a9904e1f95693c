#!/usr/bin/env python3
"""End-to-end drift of a run against KITTI poses: final position error / distance driven.

Usage: kitti_drift.py RUN.tum POSES.txt

RUN.tum: the trajectory `marglab run -o RUN.h5` writes beside its results (TUM: t x y z qx qy qz
qw, one line per frame, starting at the ground truth's first pose); POSES.txt: the KITTI poses of
the same frames (12 numbers a line, T_w_cam0). No alignment: the run starts at the first pose, so
the final position error is what the trajectory accumulated. Prints the drift [% of the ground
truth's path length], the estimate's path length / the ground truth's, and the final error split
into along and across the straight line from the first to the last ground-truth position.
Needs numpy.
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from stereo_bias import fail, read_lines  # noqa: E402


def main():
    if len(sys.argv) != 3:
        fail("usage: kitti_drift.py RUN.tum POSES.txt")
    est = np.array(read_lines(sys.argv[1], 8))[:, 1:4]
    gt = np.array(read_lines(sys.argv[2], 12))[:, [3, 7, 11]]
    if len(est) > len(gt) or len(est) < 2:
        fail("%s: %d frames, %s has %d poses" % (sys.argv[1], len(est), sys.argv[2], len(gt)))
    gt = gt[:len(est)]
    length = np.sum(np.linalg.norm(np.diff(gt, axis=0), axis=1))
    error = est[-1] - gt[-1]
    direction = (gt[-1] - gt[0]) / np.linalg.norm(gt[-1] - gt[0])
    along = float(error @ direction)
    print("drift %.2f %%  path %.4f  final error %.3f m (along %+.3f m, across %.3f m)" % (
        100 * np.linalg.norm(error) / length,
        np.sum(np.linalg.norm(np.diff(est, axis=0), axis=1)) / length,
        np.linalg.norm(error), along, np.linalg.norm(error - along * direction)))


if __name__ == "__main__":
    main()
