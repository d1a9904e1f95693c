#!/usr/bin/env python3
"""Frame-to-frame rotation of a KITTI run against its ground truth and an image-only estimate.

Usage: kitti_rotation_check.py --dataset DIR --run RUN.tum [--step N] [--last K]

DIR: a KITTI folder in the shipped layout (DIR/{calib.txt, poses.txt, image_0/}), e.g.
datasets/kitti/06_images or a `kitti_clip.py` copy. RUN.tum: the trajectory `marglab run
--dataset DIR -o RUN.h5` writes beside its results (TUM, one line per frame from frame 0).

Why. On KITTI 06 the run's end-to-end drift is a cross-track error (results/real_kitti06/README.md)
that a constant heading offset explains: the estimate's orientation leaves the ground truth's in the
first ~10 frames and then keeps its distance. Either the estimate turns wrongly there, or the
ground truth (GPS/INS) does. A third estimate decides which: the relative rotation from the left
images alone — Shi–Tomasi corners, pyramidal LK with a forward–backward check (0.3 px), the
essential matrix by RANSAC (0.5 px) and its decomposition (OpenCV), with no stereo, no calibration
of the right camera and nothing of marglab. Caveat: under forward motion a rotation about the
vertical axis and a sideways translation explain the flow almost alike (the bas-relief ambiguity),
so the 5-point rotation is trustworthy only where it has many inliers; the inlier count is printed.

Prints, per interval [k, k+N] up to frame K: the rotation vector (degrees, camera axes x right,
y down, z forward) of T_k⁻¹ T_{k+N} from the ground truth, the run and the images, and the
inliers. Needs numpy, scipy and OpenCV's Python module (python3-opencv).
"""
import argparse
import os
import sys

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from stereo_bias import fail, read_lines  # noqa: E402


def intrinsics(calib_path):
    for row in read_lines_prefixed(calib_path):
        if row[0] == "P0:":
            p = np.array([float(x) for x in row[1:13]]).reshape(3, 4)
            return p[:, :3]
    fail("%s: no P0 line" % calib_path)


def read_lines_prefixed(path):
    if not os.path.isfile(path):
        fail("%s: not found" % path)
    with open(path, encoding="utf-8") as f:
        return [line.split() for line in f if line.strip()]


def image(folder, k):
    path = os.path.join(folder, "image_0", "%06d.png" % k)
    img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if img is None:
        fail("%s: not a readable image" % path)
    return img


def image_rotation(a, b, K):
    """R_b_a (x_b = R x_a + t) from the left images alone, and its RANSAC inliers."""
    corners = cv2.goodFeaturesToTrack(a, 3000, 0.01, 7)
    ahead, st, _ = cv2.calcOpticalFlowPyrLK(a, b, corners, None, winSize=(21, 21), maxLevel=4)
    back, st_back, _ = cv2.calcOpticalFlowPyrLK(b, a, ahead, None, winSize=(21, 21), maxLevel=4)
    ok = (st[:, 0] == 1) & (st_back[:, 0] == 1) & (np.linalg.norm(back - corners, axis=2)[:, 0] < 0.3)
    p_a, p_b = corners[ok][:, 0], ahead[ok][:, 0]
    E, mask = cv2.findEssentialMat(p_a, p_b, K, cv2.RANSAC, 0.999, 0.5)
    _, R, _, inliers = cv2.recoverPose(E, p_a, p_b, K, mask=mask)
    return R, int(np.count_nonzero(inliers))


def degrees(R):
    return np.degrees(Rotation.from_matrix(R).as_rotvec())


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--run", required=True)
    ap.add_argument("--step", type=int, default=4)
    ap.add_argument("--last", type=int, default=32)
    args = ap.parse_args()
    if args.step < 1 or args.last < args.step:
        fail("--step must be >= 1 and --last >= --step")
    K = intrinsics(os.path.join(args.dataset, "calib.txt"))
    R_w_gt = [np.array(p).reshape(3, 4)[:, :3] for p in read_lines(os.path.join(args.dataset, "poses.txt"), 12)]
    run = np.array(read_lines(args.run, 8))
    R_w_run = [Rotation.from_quat(q).as_matrix() for q in run[:, 4:8]]
    last = min(args.last, len(R_w_run) - 1, len(R_w_gt) - 1)
    fmt = lambda v: "(%+.3f %+.3f %+.3f)" % tuple(v)
    print("interval    ground truth [deg]         run [deg]                  images [deg]          inliers")
    total = np.zeros((3, 3))
    for k in range(0, last - args.step + 1, args.step):
        j = k + args.step
        gt = R_w_gt[j].T @ R_w_gt[k]
        est = R_w_run[j].T @ R_w_run[k]
        img, inliers = image_rotation(image(args.dataset, k), image(args.dataset, j), K)
        total += np.array([degrees(gt), degrees(est), degrees(img)])
        print("%3d-%-3d  %s  %s  %s  %5d" % (k, j, fmt(degrees(gt)), fmt(degrees(est)),
                                             fmt(degrees(img)), inliers))
    print("sum      %s  %s  %s" % (fmt(total[0]), fmt(total[1]), fmt(total[2])))


if __name__ == "__main__":
    main()
