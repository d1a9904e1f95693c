#!/usr/bin/env python3
"""Stereo disparity bias of a KITTI track file, measured against motion stereo (no stereo baseline).

Usage: stereo_bias.py --dataset DIR --tracks TRACKS.txt [-o REPORT.md] [options]

DIR is a KITTI folder: DIR/{calib.txt, times.txt, poses.txt} (the shipped datasets/kitti/06_images)
or the download / `marglab datasets render` layout DIR/sequences/NN/{calib.txt, times.txt} with
DIR/poses/NN.txt. TRACKS.txt is a text track file from `marglab datasets track --dataset DIR -o
TRACKS.txt` (columns t_ns track_id u0 v0 u1 v1 ..., rectified pinhole pixels).

Why. A stereo VO's metric scale comes from its stereo depths z = f b / d. A disparity error δ
(d_measured = d_true + δ) scales every depth by d_true / (d_true + δ), and the trajectory with it;
a baseline error scales it by b_calib / b_true. Neither can be seen from the stereo pairs alone.
Motion stereo can: the ground-truth poses T_w_c (KITTI poses.txt: left camera cam0, from GPS/INS)
give baselines of metres between the frames of one left-camera track, independent of the stereo
baseline b and of the right camera.

Method.
  1. Each left track observed in ≥ --min-frames frames whose camera centres span ≥ --min-motion
     metres is triangulated from its left pixels alone: the point X_w minimizing the reprojection
     error Σ_k ‖π(T_c_w,k X_w) − u_k‖² (linear initialization, then Gauss–Newton). Tracks with an
     RMS residual above --max-rms px (a drifting or wrong track) are dropped.
  2. For every observation k of such a track with a right match: z_k = depth of X_w in frame k,
     the motion-stereo disparity d_motion = f b / z_k (b, f from calib.txt: b = −P1[0,3] / P1[0,0]),
     its standard deviation σ_motion from the Gauss–Newton covariance (pixel noise = the track's
     RMS residual); observations with σ_motion > --max-sigma px are dropped.
  3. The error e = (u0 − u1) − d_motion and the vertical offset v1 − v0 are summarized overall and
     binned by depth, image column, image row and disparity. A weighted least-squares fit
     e = c + s · d_motion separates an additive disparity offset c [px] (a front-end bias, or a
     yaw of the rectified right camera) from a relative error s (a baseline error: b_true =
     b_calib (1 + s)); then b_eff = b (1 + s) and the disparity offset is c.
  --orientation visual (a check on the ground truth's rotations and headings, which step 1
  trusts): two-view motion stereo instead, frame k with the first frame j ≥ --min-motion metres
  on; rotation and translation direction from the left tracks alone (essential matrix, OpenCV
  USAC_ACCURATE, 0.3 px), only the distance ‖c_j − c_k‖ from the ground truth; points triangulated
  (≤ 0.5 px in both views) with σ(f b / z) ≈ (f b / z) (0.15 px / f) / parallax ≤ --max-sigma.
  Implied scale error of the stereo depths: median over the observations of −e / (u0 − u1) (the
  relative depth error, what the VO's trajectory length inherits, to first order).

The result depends on the ground truth's scale and on f only through the pixel angles (motion
depth ∝ f at fixed pixels, so f cancels in f b / z); it measures the stereo disparity against b.

Needs numpy. Deterministic. Exit 1 with a message naming the file and line on bad input.
"""
import argparse
import math
import os
import sys

import numpy as np


def fail(msg):
    print(os.path.basename(sys.argv[0]) + ": " + msg, file=sys.stderr)
    sys.exit(1)


def numbers(path, line_no, text, count):
    try:
        vals = [float(x) for x in text.split()]
    except ValueError:
        fail("%s:%d: expected %d numbers, found %r" % (path, line_no, count, text.strip()[:80]))
    if len(vals) != count or not all(math.isfinite(v) for v in vals):
        fail("%s:%d: expected %d finite numbers, found %d" % (path, line_no, count, len(vals)))
    return vals


def kitti_files(folder):
    """(calib, times, poses) paths of the shipped or the download/rendered layout."""
    if os.path.isfile(os.path.join(folder, "calib.txt")):
        return [os.path.join(folder, n) for n in ("calib.txt", "times.txt", "poses.txt")]
    seqs = os.path.join(folder, "sequences")
    names = sorted(os.listdir(seqs)) if os.path.isdir(seqs) else []
    if len(names) != 1:
        fail("%s: expected calib.txt or sequences/NN/ with one sequence" % folder)
    seq = os.path.join(seqs, names[0])
    return [os.path.join(seq, "calib.txt"), os.path.join(seq, "times.txt"),
            os.path.join(folder, "poses", names[0] + ".txt")]


def read_calib(path):
    P = {}
    with open(path, encoding="utf-8") as f:
        for i, line in enumerate(f, 1):
            key, _, rest = line.partition(":")
            if key.strip() in ("P0", "P1"):
                P[key.strip()] = np.array(numbers(path, i, rest, 12)).reshape(3, 4)
    if "P0" not in P or "P1" not in P:
        fail("%s: expected lines P0: and P1: (12 numbers each)" % path)
    f, cx, cy = P["P0"][0, 0], P["P0"][0, 2], P["P0"][1, 2]
    if f <= 0 or P["P1"][0, 3] >= 0:
        fail("%s: expected f > 0 and a right camera to the right (P1[0,3] < 0)" % path)
    return f, cx, cy, -P["P1"][0, 3] / P["P1"][0, 0]


def read_lines(path, count):
    if not os.path.isfile(path):
        fail("%s: not found" % path)
    with open(path, encoding="utf-8") as f:
        return [numbers(path, i, line, count) for i, line in enumerate(f, 1) if line.strip()]


def read_tracks(path, t_ns_of_frame, frames=None):
    """{track_id: [(frame, u0, v0, u1, v1), ...]} (u1, v1 nan without a match); only the
    observations of frames [first, last] when frames = (first, last)."""
    frame_of = {t: k for k, t in enumerate(t_ns_of_frame)}
    tracks = {}
    if not os.path.isfile(path):
        fail("%s: not found" % path)
    with open(path, encoding="utf-8") as f:
        for i, line in enumerate(f, 1):
            if line.startswith("#") or not line.strip():
                continue
            parts = line.split()
            if len(parts) < 6:
                fail("%s:%d: expected t_ns track_id u0 v0 u1 v1 ..." % (path, i))
            try:
                t, tid = int(parts[0]), int(parts[1])
                u0, v0, u1, v1 = (float(x) for x in parts[2:6])
            except ValueError:
                fail("%s:%d: expected integers t_ns track_id and four pixel numbers" % (path, i))
            k = frame_of.get(t)
            if k is None:
                fail("%s:%d: t_ns %d is not a frame time of times.txt" % (path, i, t))
            if frames and not frames[0] <= k <= frames[1]:
                continue
            tracks.setdefault(tid, []).append((k, u0, v0, u1, v1))
    return tracks


def triangulate(obs, T_c_w, f, cx, cy, iterations=10):
    """X_w, RMS residual [px], 3x3 covariance per px² of the left-only reprojection LSQ."""
    A, rhs = [], []
    for k, u, v, *_ in obs:  # linear: bearing × (R X + t) = 0, two rows per observation
        R, t = T_c_w[k][:3, :3], T_c_w[k][:3, 3]
        x, y = (u - cx) / f, (v - cy) / f
        A += [R[0] - x * R[2], R[1] - y * R[2]]
        rhs += [x * t[2] - t[0], y * t[2] - t[1]]
    X = np.linalg.lstsq(np.array(A), np.array(rhs), rcond=None)[0]
    for _ in range(iterations):
        J, r = [], []
        for k, u, v, *_ in obs:
            R, t = T_c_w[k][:3, :3], T_c_w[k][:3, 3]
            p = R @ X + t
            if p[2] <= 0.1:
                return None
            r += [f * p[0] / p[2] + cx - u, f * p[1] / p[2] + cy - v]
            dp = np.array([[f / p[2], 0, -f * p[0] / p[2] ** 2],
                           [0, f / p[2], -f * p[1] / p[2] ** 2]])
            J += list(dp @ R)
        J, r = np.array(J), np.array(r)
        H = J.T @ J
        if np.linalg.cond(H) > 1e12:
            return None
        step = np.linalg.solve(H, -J.T @ r)
        X = X + step
        if np.linalg.norm(step) < 1e-9:
            break
    rms = math.sqrt(float(r @ r) / len(r))
    return X, rms, np.linalg.inv(H)


def measure(tracks, T_c_w, centres, calib, args):
    """Rows (u0, v0, d_meas, d_motion, sigma, z, v1 - v0) of the usable stereo observations."""
    f, cx, cy, b = calib
    rows, used = [], 0
    for obs in tracks.values():
        if len(obs) < args.min_frames:
            continue
        c = centres[[o[0] for o in obs]]
        if np.max(np.linalg.norm(c - c[0], axis=1)) < args.min_motion:
            continue
        tri = triangulate(obs, T_c_w, f, cx, cy)
        if tri is None or tri[1] > args.max_rms:
            continue
        X, rms, cov = tri
        used += 1
        for k, u0, v0, u1, v1 in obs:
            if math.isnan(u1):
                continue
            R, t = T_c_w[k][:3, :3], T_c_w[k][:3, 3]
            z = float(R[2] @ X + t[2])
            grad = -f * b / z ** 2 * R[2]  # d(f b / z) / dX_w
            sigma = math.sqrt(float(grad @ cov @ grad)) * max(rms, args.min_noise)
            if sigma <= args.max_sigma:
                rows.append((u0, v0, u0 - u1, f * b / z, sigma, z, v1 - v0))
    return np.array(rows).reshape(-1, 7), used


def measure_visual(tracks, T_w_c, centres, calib, args):
    """measure()'s rows from two-view motion stereo with the images' own relative orientation."""
    import cv2  # only this mode needs OpenCV's Python bindings
    f, cx, cy, b = calib
    by_frame = {}
    for tid, obs in tracks.items():
        for k, u0, v0, u1, v1 in obs:
            by_frame.setdefault(k, {})[tid] = (u0, v0, u1, v1)
    rows, pairs = [], 0
    for k in sorted(by_frame):
        far = [j for j in sorted(by_frame) if j > k and
               np.linalg.norm(centres[j] - centres[k]) >= args.min_motion]
        if not far:
            break
        j = far[0]
        ids = [i for i in by_frame[k] if i in by_frame[j]]
        if len(ids) < 30:
            continue
        q_k = np.array([[(by_frame[k][i][0] - cx) / f, (by_frame[k][i][1] - cy) / f] for i in ids])
        q_j = np.array([[(by_frame[j][i][0] - cx) / f, (by_frame[j][i][1] - cy) / f] for i in ids])
        E, mask = cv2.findEssentialMat(q_k, q_j, np.eye(3), method=cv2.USAC_ACCURATE,
                                       prob=0.9999, threshold=0.3 / f)
        if E is None or E.shape != (3, 3):
            continue
        _, R, t, mask = cv2.recoverPose(E, q_k, q_j, np.eye(3), mask=mask)
        t = t.ravel() * np.linalg.norm(centres[j] - centres[k])
        X = cv2.triangulatePoints(np.hstack([np.eye(3), np.zeros((3, 1))]),
                                  np.hstack([R, t[:, None]]), q_k.T, q_j.T)
        pairs += 1
        for i, x, inlier, a, c in zip(ids, (X[:3] / X[3]).T, mask.ravel(), q_k, q_j):
            u0, v0, u1, v1 = by_frame[k][i]
            x_j = R @ x + t
            if not inlier or math.isnan(u1) or x[2] <= 1 or x_j[2] <= 1:
                continue
            if f * max(np.hypot(*(x[:2] / x[2] - a)), np.hypot(*(x_j[:2] / x_j[2] - c))) > 0.5:
                continue
            parallax = math.acos(min(1.0, float(x @ (R.T @ x_j)) / np.linalg.norm(x) /
                                     np.linalg.norm(x_j)))
            d = f * b / x[2]
            sigma = d * (0.15 / f) / max(parallax, 1e-9)
            if sigma <= args.max_sigma:
                rows.append((u0, v0, u0 - u1, d, sigma, x[2], v1 - v0))
    return np.array(rows).reshape(-1, 7), pairs


def fit_offset_scale(d_motion, e, w):
    """Weighted LSQ e = c + s d_motion; (c, s, σ_c, σ_s) with the residuals' scatter."""
    A = np.stack([np.ones_like(d_motion), d_motion], axis=1) * np.sqrt(w)[:, None]
    y = e * np.sqrt(w)
    sol, *_ = np.linalg.lstsq(A, y, rcond=None)
    dof = max(len(e) - 2, 1)
    s2 = float(np.sum((A @ sol - y) ** 2)) / dof
    cov = s2 * np.linalg.inv(A.T @ A)
    return sol[0], sol[1], math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])


def table(title, key, edges, rows, unit):
    e = rows[:, 2] - rows[:, 3]
    out = ["", "### by %s" % title, "",
           "| %s | n | mean e [px] | median e [px] | ± (s.e.) | median rel. depth error | "
           "median v1−v0 [px] |" % unit, "|---|---:|---:|---:|---:|---:|---:|"]
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = (key >= lo) & (key < hi)
        n = int(m.sum())
        if n < 5:
            continue
        se = float(np.std(e[m])) / math.sqrt(n)
        out.append("| %g–%g | %d | %+.3f | %+.3f | %.3f | %+.2f %% | %+.3f |" % (
            lo, hi, n, np.mean(e[m]), np.median(e[m]), se,
            100 * np.median(-e[m] / rows[m, 2]), np.median(rows[m, 6])))
    return out


def report(rows, used, n_tracks, calib, args):
    f, cx, cy, b = calib
    e = rows[:, 2] - rows[:, 3]
    w = 1.0 / (rows[:, 4] ** 2 + args.min_noise ** 2)
    c, s, sc, ss = fit_offset_scale(rows[:, 3], e, w)
    rel = -e / rows[:, 2]
    out = ["# Stereo disparity vs motion stereo", "",
           "dataset `%s`, tracks `%s`, frames %s" % (args.dataset, args.tracks,
                                                      args.frames or "all"), "",
           "calibration: f = %.4f px, cx = %.4f, cy = %.4f, b = %.6f m (f b = %.3f px m)" % (
               f, cx, cy, b, f * b),
           "settings: orientation %s, min_frames %d, min_motion %.2f m, max_rms %.2f px, "
           "max_sigma %.2f px" % (args.orientation, args.min_frames, args.min_motion, args.max_rms,
                                  args.max_sigma), "",
           "tracks: %d in the file, %d %s; %d stereo observations used" % (
               n_tracks, used, "triangulated from motion" if args.orientation == "gt" else
               "frame pairs (visual orientation)", len(rows)), "",
           "e = (u0 − u1) − f b / z_motion  [px]", "",
           "| statistic | value |", "|---|---:|",
           "| mean e | %+.4f px (s.e. %.4f) |" % (np.mean(e), np.std(e) / math.sqrt(len(e))),
           "| median e | %+.4f px |" % np.median(e),
           "| weighted fit e = c + s·d: c | %+.4f ± %.4f px |" % (c, sc),
           "| weighted fit: s | %+.5f ± %.5f (b_eff = %.5f m) |" % (s, ss, b * (1 + s)),
           "| median relative depth error −e/d | %+.3f %% |" % (100 * np.median(rel)),
           "| median v1 − v0 | %+.4f px |" % np.median(rows[:, 6])]
    out += table("depth z_motion", rows[:, 5], [0, 8, 12, 16, 20, 30, 45, 1e9], rows, "z [m]")
    out += table("disparity u0 − u1", rows[:, 2], [0, 10, 15, 20, 30, 45, 70, 1e9], rows,
                 "d [px]")
    out += table("image column u0", rows[:, 0], [0, 200, 400, 600, 800, 1000, 1300], rows,
                 "u0 [px]")
    out += table("image row v0", rows[:, 1], [0, 100, 150, 200, 250, 300, 400], rows, "v0 [px]")
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", required=True, help="KITTI folder (see the module docstring)")
    ap.add_argument("--tracks", required=True, help="text track file of `marglab datasets track`")
    ap.add_argument("-o", "--output", help="write the markdown report here (else stdout)")
    ap.add_argument("--orientation", choices=["gt", "visual"], default="gt",
                    help="poses of the motion stereo: ground truth, or the images' essential "
                         "matrix with the ground truth's distance only")
    ap.add_argument("--frames", help="FIRST:LAST, only these frames' observations (0-based, "
                                      "inclusive), e.g. to measure on half of a clip and test "
                                      "the correction on the other half")
    ap.add_argument("--min-frames", type=int, default=4)
    ap.add_argument("--min-motion", type=float, default=2.0, help="camera travel [m] in a track")
    ap.add_argument("--max-rms", type=float, default=0.5, help="left reprojection RMS [px]")
    ap.add_argument("--max-sigma", type=float, default=0.15,
                    help="σ of f b / z_motion [px] above which an observation is dropped")
    ap.add_argument("--min-noise", type=float, default=0.05,
                    help="pixel noise floor [px] for the covariance and the weights")
    args = ap.parse_args()
    calib_path, times_path, poses_path = kitti_files(args.dataset)
    calib = read_calib(calib_path)
    t_ns = [int(round(t[0] * 1e9)) for t in read_lines(times_path, 1)]
    poses = read_lines(poses_path, 12)
    if len(poses) < len(t_ns):
        fail("%s: %d poses for %d frames of %s" % (poses_path, len(poses), len(t_ns), times_path))
    T_w_c = [np.vstack([np.array(p).reshape(3, 4), [0, 0, 0, 1]]) for p in poses[:len(t_ns)]]
    T_c_w = [np.linalg.inv(T) for T in T_w_c]
    centres = np.array([T[:3, 3] for T in T_w_c])
    frames = None
    if args.frames:
        try:
            frames = tuple(int(x) for x in args.frames.split(":"))
        except ValueError:
            frames = ()
        if len(frames) != 2 or not 0 <= frames[0] <= frames[1]:
            fail("--frames %r: expected FIRST:LAST with 0 <= FIRST <= LAST" % args.frames)
    tracks = read_tracks(args.tracks, t_ns, frames)
    if args.orientation == "gt":
        rows, used = measure(tracks, T_c_w, centres, calib, args)
    else:
        rows, used = measure_visual(tracks, T_w_c, centres, calib, args)
    if len(rows) < 10:
        fail("%s: only %d usable stereo observations (too little motion or too few long tracks)"
             % (args.tracks, len(rows)))
    text = report(rows, used, len(tracks), calib, args)
    if args.output:
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        from atomic_save import write_text
        write_text(args.output, text)
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
