#!/usr/bin/env python3
"""The front-end's stereo matches re-measured by an independent matcher (phase correlation).

Usage: stereo_phase_check.py --dataset DIR --tracks TRACKS.txt

DIR: a KITTI folder in the shipped layout (DIR/{times.txt, image_0/, image_1/}, e.g.
datasets/kitti/06_images); TRACKS.txt: `marglab datasets track --dataset DIR -o TRACKS.txt`.

Why. stereo_bias.py finds the real frames' disparities below motion stereo. If Lucas–Kanade's
sub-pixel estimate were biased (pixel-centre conventions, the right image's gain normalization,
the window), a matcher built on another principle would disagree with it. For every stereo match,
the 32×32 patches around the rounded left and right keypoints (Hann window) are phase-correlated
(cv2.phaseCorrelate, peak response ≥ 0.3); the printed numbers are the median differences LK −
phase correlation of the disparity, and both matchers' vertical offsets v1 − v0 by image column
and row, and as a map over the image (a vertical offset in rectified images is the
rectification's, not a matcher's: rendered frames give 0.000 px with LK). Needs numpy and
OpenCV's Python bindings.
"""
import argparse
import math
import os
import sys

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from stereo_bias import fail, read_lines, read_tracks  # noqa: E402

HALF = 16  # patch half-size [px]


def matches(tracks):
    return sorted((k, u0, v0, u1, v1) for obs in tracks.values()
                  for k, u0, v0, u1, v1 in obs if not math.isnan(u1))


def phase_rows(dataset, stereo):
    """Rows (u0, v0, disparity LK, v1 − v0 LK, disparity PC, v1 − v0 PC)."""
    window = cv2.createHanningWindow((2 * HALF, 2 * HALF), cv2.CV_64F)
    rows, images = [], {}
    for k, u0, v0, u1, v1 in stereo:
        if k not in images:
            paths = [os.path.join(dataset, cam, "%06d.png" % k) for cam in ("image_0", "image_1")]
            pair = [cv2.imread(p, cv2.IMREAD_GRAYSCALE) for p in paths]
            if any(im is None for im in pair):
                fail("%s: cannot read the stereo images of frame %d" % (dataset, k))
            images = {k: [im.astype(np.float64) for im in pair]}
        left, right = images[k]
        a0, b0, a1, b1 = (int(round(x)) for x in (u0, v0, u1, v1))
        if (min(a0, a1, b0, b1) < HALF or max(a0, a1) + HALF > left.shape[1]
                or max(b0, b1) + HALF > left.shape[0]):
            continue
        # Contiguous copies: on views into the image, cv2.phaseCorrelate (OpenCV 4.6) gave
        # results that depended on the previous calls.
        patch0 = np.ascontiguousarray(left[b0 - HALF:b0 + HALF, a0 - HALF:a0 + HALF])
        patch1 = np.ascontiguousarray(right[b1 - HALF:b1 + HALF, a1 - HALF:a1 + HALF])
        (sx, sy), response = cv2.phaseCorrelate(patch0, patch1, window)
        if response >= 0.3:
            rows.append((u0, v0, u0 - u1, v1 - v0, a0 - (a1 + sx), b1 + sy - b0))
    return np.array(rows).reshape(-1, 6)


def offset_map(r, col):
    """Median of r[:, col] (a vertical offset) over a 6×6 grid of the image, as text."""
    u_edges, v_edges = (0, 200, 400, 600, 800, 1000, 1300), (0, 60, 120, 180, 240, 300, 400)
    lines = ["v0 \\ u0   " + " ".join("%4d–%-4d" % e for e in zip(u_edges[:-1], u_edges[1:]))]
    for v_lo, v_hi in zip(v_edges[:-1], v_edges[1:]):
        cells = []
        for u_lo, u_hi in zip(u_edges[:-1], u_edges[1:]):
            m = (r[:, 0] >= u_lo) & (r[:, 0] < u_hi) & (r[:, 1] >= v_lo) & (r[:, 1] < v_hi)
            cells.append("%+9.2f" % np.median(r[m, col]) if m.sum() >= 10 else "       --")
        lines.append("%3d–%-3d    " % (v_lo, v_hi) + " ".join(cells))
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--tracks", required=True)
    args = ap.parse_args()
    t_ns = [int(round(t[0] * 1e9)) for t in read_lines(os.path.join(args.dataset, "times.txt"), 1)]
    r = phase_rows(args.dataset, matches(read_tracks(args.tracks, t_ns)))
    if len(r) < 10:
        fail("%s: only %d matches could be phase-correlated" % (args.tracks, len(r)))
    print("%d matches; disparity LK − phase correlation: median %+.3f px, mean %+.3f px" % (
        len(r), np.median(r[:, 2] - r[:, 4]), np.mean(r[:, 2] - r[:, 4])))
    print("v1 − v0: LK median %+.3f px, phase correlation median %+.3f px" % (
        np.median(r[:, 3]), np.median(r[:, 5])))
    for col, name, edges in ((0, "u0", (0, 300, 600, 900, 1300)), (1, "v0", (0, 120, 240, 400))):
        for lo, hi in zip(edges[:-1], edges[1:]):
            m = (r[:, col] >= lo) & (r[:, col] < hi)
            if m.sum() >= 5:
                print("%s %4d–%-4d n %5d: v1 − v0 LK %+.3f, PC %+.3f; disparity LK − PC %+.3f" % (
                    name, lo, hi, m.sum(), np.median(r[m, 3]), np.median(r[m, 5]),
                    np.median(r[m, 2] - r[m, 4])))
    for col, name in ((3, "LK"), (5, "phase correlation")):
        print("\nmedian v1 − v0 [px], %s (≥ 10 matches a cell):\n%s" % (name, offset_map(r, col)))


if __name__ == "__main__":
    main()
