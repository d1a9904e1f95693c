#!/usr/bin/env python3
"""A KITTI folder of some frames of another, optionally with the right camera's cx moved.

Usage: kitti_clip.py --dataset DIR --frames FIRST:LAST [--right-cx-shift PX] -o OUT

DIR: a KITTI folder in the shipped layout (DIR/{calib.txt, times.txt, poses.txt, image_0/,
image_1/}, e.g. datasets/kitti/06_images) or the download's dataset/sequences/NN, whose poses are
dataset/poses/NN.txt. OUT (must not exist) gets frames FIRST..LAST
(inclusive, renumbered from 000000), their times from 0 and their poses relative to frame FIRST
(T_FIRST⁻¹ T_k), in the same layout, so that `marglab run --dataset OUT` runs on that clip.

--right-cx-shift PX adds PX to the principal point cx of P1 (the right camera) in OUT's calib.txt:
every disparity u0 − u1 grows by PX, the correction of a disparity offset measured by
tools/scripts/stereo_bias.py (results/real_kitti06/README.md). The shipped calib.txt is never
changed; this writes a copy.

Written into a new OUT.tmp-XXXXXXXX (mkdtemp) and renamed onto OUT at the end (nothing
half-written on an error or a signal). Needs numpy.
"""
import argparse
import math
import os
import shutil
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import atomic_save  # noqa: E402
from stereo_bias import fail, read_lines  # noqa: E402


def poses_path(src):
    """DIR/poses.txt, else the download layout's dataset/poses/NN.txt beside sequences/NN."""
    own = os.path.join(src, "poses.txt")
    if os.path.isfile(own):
        return own
    seq = os.path.abspath(src).rstrip("/")
    official = os.path.join(os.path.dirname(os.path.dirname(seq)), "poses",
                            os.path.basename(seq) + ".txt")
    return official if os.path.isfile(official) else own


def shifted_calib(path, shift_px):
    """calib.txt's lines with P1's cx (its third number) moved by shift_px."""
    out, found = [], False
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("P1:"):
                values = line.split()[1:]
                if len(values) != 12:
                    fail("%s: expected 12 numbers after P1:" % path)
                values[2] = "%.12e" % (float(values[2]) + shift_px)
                line, found = "P1: " + " ".join(values) + "\n", True
            out.append(line)
    if not found:
        fail("%s: no P1: line" % path)
    return "".join(out)


def write_clip(src, first, last, shift_px, tmp):
    times = read_lines(os.path.join(src, "times.txt"), 1)
    poses = read_lines(poses_path(src), 12)
    if last >= min(len(times), len(poses)):
        fail("%s: --frames ends at %d, the folder has %d frames with poses" % (
            src, last, min(len(times), len(poses))))
    T_first_inv = np.linalg.inv(np.vstack([np.reshape(poses[first], (3, 4)), [0, 0, 0, 1]]))
    for cam in ("image_0", "image_1"):
        os.makedirs(os.path.join(tmp, cam))
    with open(os.path.join(tmp, "times.txt"), "w", encoding="utf-8") as t_out, \
            open(os.path.join(tmp, "poses.txt"), "w", encoding="utf-8") as p_out:
        for i, k in enumerate(range(first, last + 1)):
            for cam in ("image_0", "image_1"):
                image = os.path.join(src, cam, "%06d.png" % k)
                if not os.path.isfile(image):
                    fail("%s: not found" % image)
                shutil.copyfile(image, os.path.join(tmp, cam, "%06d.png" % i))
            t_out.write("%.9e\n" % (times[k][0] - times[first][0]))
            T = T_first_inv @ np.vstack([np.reshape(poses[k], (3, 4)), [0, 0, 0, 1]])
            p_out.write(" ".join("%.12e" % x for x in T[:3].ravel()) + "\n")
    with open(os.path.join(tmp, "calib.txt"), "w", encoding="utf-8") as c_out:
        c_out.write(shifted_calib(os.path.join(src, "calib.txt"), shift_px))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--frames", required=True, help="FIRST:LAST (0-based, inclusive)")
    ap.add_argument("--right-cx-shift", type=float, default=0.0, help="[px] added to P1's cx")
    ap.add_argument("-o", "--output", required=True)
    args = ap.parse_args()
    try:
        first, last = (int(x) for x in args.frames.split(":"))
    except ValueError:
        first, last = 0, -1
    if not 0 <= first < last:
        fail("--frames %r: expected FIRST:LAST with 0 <= FIRST < LAST" % args.frames)
    if not math.isfinite(args.right_cx_shift):
        fail("--right-cx-shift %r: expected a finite number of pixels" % args.right_cx_shift)
    if os.path.exists(args.output):
        fail("%s: exists (give a new folder)" % args.output)
    parent = os.path.dirname(os.path.abspath(args.output.rstrip("/")))
    if not os.path.isdir(parent) or not os.access(parent, os.W_OK):
        fail("%s: expected an existing folder this process may write, for -o %s"
             % (parent, args.output))
    tmp = tempfile.mkdtemp(prefix=os.path.basename(args.output.rstrip("/")) + ".tmp-",
                           dir=parent)
    try:
        write_clip(args.dataset, first, last, args.right_cx_shift, tmp)
        os.rename(tmp, args.output)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print("wrote %s: frames %d-%d of %s, P1 cx %+g px" % (
        args.output, first, last, args.dataset, args.right_cx_shift))


if __name__ == "__main__":
    atomic_save.unwind_on_stop_signals()  # the temporary folder is removed on the way out
    atomic_save.run_main(main, "kitti_clip.py")
