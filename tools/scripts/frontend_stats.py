#!/usr/bin/python3
"""What the simulator assumes, measured on a track stream at a run's converged estimate.

For each source (real image tracks, simulated tracks) the script reads the track file (HDF5,
core/sim/track_io.h), the run's results file (its frames; with --gt their ground-truth poses, else
its /frames p_est, q_est) and the stereo calibration: EuRoC mav0/cam*/sensor.yaml (T_BS and the
pinhole intrinsics of the undistorted image the tracks are in), or a KITTI sequence folder's
calib.txt (rectified P0, P1: body = cam0, cam1 at x = +b with b = -P1[0,3] / P1[0,0]); the KITTI
ground truth is the folder's poses.txt (T_w_c0 per line) at its times.txt. --right-cx-shift adds
to cam1's cx for the first source (the real frames), i.e. to every predicted disparity: a known
rectification bias (results/real_kitti06: KITTI 06 disparities 0.22 px too small) is then not
counted as front-end noise. Each track's landmark is triangulated at those poses (Gauss-Newton on
all its cam0 and cam1 pixels, Huber-weighted so that a wrong association does not drag the point);
--refine-poses rounds then refine each frame's pose on its pixels and re-triangulate (a bundle
adjustment by blocks: the converged estimate), so that the poses' own error (mocap noise; the VIO
estimate's yaw drift) is not counted as front-end noise. The residuals r = uv - pi(T_w_c^-1 p_w)
give:
  residuals   quantiles of |r| per coordinate and of the norm, robust sigma (1.4826 MAD), excess
              kurtosis, a Student-t fit (nu, scale) against a Gaussian (log-likelihood);
  outliers    share of observations whose cam0 or cam1 residual norm exceeds --outlier-px;
  drift       the variogram of a track's cam0 residual, E[(r(k+L) - r(k))^2] = 2 s_w^2 + L q
              per coordinate (white noise s_w plus a random walk of step sqrt(q) per frame);
  tracks      length (frames per track id, censored by the clip), loss hazard per frame,
              the share of tracks continued from one frame to the next, features per frame,
              stereo share, depth at the first observation.
  epipolar    the Sampson distance of every stereo match to the calibration's epipolar
              constraint (one noise component per match, no depth needed): median, robust sigma,
              Student-t fit;
  consecutive the share of a frame's tracks found again in the next camera frame, over the pairs of
              consecutive frames.
Lags and consecutive frames count camera frames (the shortest gap between the frames is one), so
non-consecutive keyframes work: --source NAME TRACKS gt takes the track file's frames inside the
--gt trajectory (no run), --consecutive-residuals measures residuals, outliers and drift only on
frames with a consecutive neighbour, and --loss-from takes the track loss, which keyframes cannot
measure, from another profile.
With --profile-out it writes the `realistic` simulator profile calibrated on the first source
against the second (docs/design.md §5); with --loss-from, the `realistic-motion` one with the
origin of each number as a comment. Output: frontend_stats.json and frontend_stats.md in --out.
"""

import argparse
import gzip
import json
import math
import os
import re
import sys

import h5py
import numpy as np
from scipy import stats as sstats

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from atomic_save import atomic_path  # noqa: E402


def fail(message):
    print(f"frontend_stats.py: {message}", file=sys.stderr)
    sys.exit(1)


# ---------------------------------------------------------------- input


def read_sensor_yaml(path):
    """T_BS (4x4) and intrinsics (fx, fy, cx, cy) of an EuRoC sensor.yaml (regex: %YAML:1.0)."""
    try:
        text = open(path, encoding="utf-8").read()
    except OSError as e:
        fail(f"{path}: cannot read ({e.strerror})")
    t = re.search(r"T_BS:.*?data:\s*\[([^\]]*)\]", text, re.S)
    k = re.search(r"intrinsics:\s*\[([^\]]*)\]", text)
    if not t or not k:
        fail(f"{path}: expected T_BS data and intrinsics")
    T = np.array([float(x) for x in t.group(1).replace("\n", " ").split(",")])
    K = [float(x) for x in k.group(1).split(",")]
    if T.size != 16 or len(K) != 4:
        fail(f"{path}: expected 16 T_BS values and 4 intrinsics")
    return T.reshape(4, 4), K


def read_kitti_calib(path, right_cx_shift_px):
    """(T_b_c0, K0), (T_b_c1, K1) of a KITTI calib.txt (rectified P0, P1; body = cam0)."""
    P = {}
    try:
        for n, line in enumerate(open(path, encoding="utf-8"), 1):
            key, _, rest = line.partition(":")
            if key.strip() in ("P0", "P1"):
                values = [float(x) for x in rest.split()]
                if len(values) != 12:
                    fail(f"{path}:{n}: expected 12 numbers after {key.strip()}:")
                P[key.strip()] = np.array(values).reshape(3, 4)
    except OSError as e:
        fail(f"{path}: cannot read ({e.strerror})")
    except ValueError:
        fail(f"{path}:{n}: expected numbers")
    if set(P) != {"P0", "P1"}:
        fail(f"{path}: expected lines P0: and P1:")
    K = [[M[0, 0], M[1, 1], M[0, 2], M[1, 2]] for M in (P["P0"], P["P1"])]
    K[1][2] += right_cx_shift_px
    T_b_c1 = np.eye(4)
    T_b_c1[0, 3] = -(P["P1"][0, 3] - P["P0"][0, 3]) / P["P1"][0, 0]
    return (np.eye(4), K[0]), (T_b_c1, K[1])


def quat_to_R(q):
    """Rotation matrices from quaternions x y z w (n, 4)."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def read_run(path):
    """Frame times and T_w_b (VIO) or T_w_c0 (VO) of a results file, and its mode."""
    try:
        with h5py.File(path, "r") as f:
            t = f["frames/t_ns"][:]
            p = f["frames/p_est"][:]
            q = f["frames/q_est"][:]
            mode = f.attrs["mode"]
            status = f.attrs["status"]
    except (OSError, KeyError) as e:
        fail(f"{path}: not a readable results file ({e})")
    mode = mode.decode() if isinstance(mode, bytes) else str(mode)
    status = status.decode() if isinstance(status, bytes) else str(status)
    if status != "ok":
        fail(f"{path}: the run failed; its estimate is not converged")
    return t, quat_to_R(q), p, mode


def read_gt_poses(path, t_ns):
    """Body poses (R_w_b, p_w_b) at t_ns from a TUM ground-truth file (seconds; gzip allowed):
    positions interpolated linearly, quaternions by normalized linear interpolation."""
    try:
        gt = np.loadtxt(gzip.open(path, "rt") if path.endswith(".gz") else path, ndmin=2)
    except (OSError, ValueError) as e:
        fail(f"{path}: not a readable TUM trajectory ({e})")
    t = np.round(gt[:, 0] * 1e9)
    if gt.shape[1] != 8 or np.any(t_ns < t[0]) or np.any(t_ns > t[-1]):
        fail(f"{path}: expected 8 columns covering the run's frames")
    i = np.clip(np.searchsorted(t, t_ns) - 1, 0, len(t) - 2)
    a = ((t_ns - t[i]) / (t[i + 1] - t[i]))[:, None]
    p = (1 - a) * gt[i, 1:4] + a * gt[i + 1, 1:4]
    q0, q1 = gt[i, 4:8], gt[i + 1, 4:8]
    q1 = np.where(np.sum(q0 * q1, axis=1, keepdims=True) < 0, -q1, q1)
    q = (1 - a) * q0 + a * q1
    return quat_to_R(q / np.linalg.norm(q, axis=1, keepdims=True)), p


def read_kitti_poses(path, t_ns):
    """Camera-0 poses (R_w_c0, p_w_c0) at the frame times t_ns from a KITTI poses.txt (3x4 T_w_c0
    per line) and the times.txt beside it (seconds): the runs' frames are its frames."""
    times = os.path.join(os.path.dirname(path), "times.txt")
    try:
        T = np.loadtxt(path, ndmin=2)
        t = np.round(np.loadtxt(times, ndmin=1) * 1e9).astype(np.int64)
    except (OSError, ValueError) as e:
        fail(f"{path}: not a readable KITTI poses.txt with times.txt beside it ({e})")
    if T.shape[1] != 12 or len(T) != len(t):
        fail(f"{path}: expected 12 columns and one line per line of {times}")
    row = {int(x): i for i, x in enumerate(t)}
    missing = [int(x) for x in t_ns if int(x) not in row]
    if missing:
        fail(f"{times}: no frame at the run's t_ns {missing[0]}")
    T = T[[row[int(x)] for x in t_ns]].reshape(-1, 3, 4)
    return T[:, :, :3], T[:, :, 3]


def read_tracks(path):
    try:
        with h5py.File(path, "r") as f:
            o = f["observations"]
            data = {k: o[k][:] for k in ("offsets", "track_id", "u0", "v0", "has_right", "u1", "v1")}
            data["t_ns"] = f["frames/t_ns"][:]
    except (OSError, KeyError) as e:
        fail(f"{path}: not a readable marglab-tracks HDF5 file ({e})")
    return data


# ---------------------------------------------------------------- geometry


class Rig:
    def __init__(self, folder, right_cx_shift_px=0.0):
        """EuRoC mav0 folder (cam0/1 sensor.yaml) or KITTI sequence folder (calib.txt)."""
        kitti = os.path.join(folder, "calib.txt")
        if os.path.isfile(kitti):
            (self.T_b_c0, self.K0), (self.T_b_c1, self.K1) = read_kitti_calib(
                kitti, right_cx_shift_px)
            return
        (self.T_b_c0, self.K0) = read_sensor_yaml(os.path.join(folder, "cam0", "sensor.yaml"))
        (self.T_b_c1, self.K1) = read_sensor_yaml(os.path.join(folder, "cam1", "sensor.yaml"))
        self.K1[2] += right_cx_shift_px

    def cameras(self, R_w_s, p_w_s, mode):
        """Per frame (R_c_w, p_w_c) of cam0 and cam1 from the run's state poses."""
        out = []
        T_s_c0 = np.eye(4) if mode == "vo" else self.T_b_c0
        T_c0_c1 = np.linalg.inv(self.T_b_c0) @ self.T_b_c1
        for T_s_c in (T_s_c0, T_s_c0 @ T_c0_c1):
            R_w_c = R_w_s @ T_s_c[:3, :3]
            p_w_c = np.einsum("nij,j->ni", R_w_s, T_s_c[:3, 3]) + p_w_s
            out.append((np.transpose(R_w_c, (0, 2, 1)), p_w_c))
        return out


def project(K, R_c_w, p_w_c, X):
    """Pixels (n, 2), depths (n) and the Jacobian d uv / d X (n, 2, 3) of X in each camera."""
    p_c = np.einsum("nij,nj->ni", R_c_w, X - p_w_c)
    z = p_c[:, 2]
    uv = np.stack([K[0] * p_c[:, 0] / z + K[2], K[1] * p_c[:, 1] / z + K[3]], -1)
    J_c = np.zeros((len(z), 2, 3))
    J_c[:, 0, 0] = K[0] / z
    J_c[:, 0, 2] = -K[0] * p_c[:, 0] / z**2
    J_c[:, 1, 1] = K[1] / z
    J_c[:, 1, 2] = -K[1] * p_c[:, 1] / z**2
    return uv, z, np.einsum("nij,njk->nik", J_c, R_c_w)


def ray(K, R_c_w, p_w_c, uv):
    d_c = np.array([(uv[0] - K[2]) / K[0], (uv[1] - K[3]) / K[1], 1.0])
    return p_w_c, R_c_w.T @ d_c


def initial_point(views):
    """Least-squares intersection of the viewing rays (minimum-distance point)."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for origin, d in views:
        d = d / np.linalg.norm(d)
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ origin
    if np.linalg.cond(A) > 1e8:
        return None
    return np.linalg.solve(A, b)


def triangulate(cam, R, p, uv, huber_px=1.0, iterations=15):
    """Huber-IRLS Gauss-Newton landmark from its pixels uv (n, 2) in cameras cam (0/1) at the
    poses R_c_w (n, 3, 3), p_w_c (n, 3); None when the rays do not fix a point in front."""
    X = initial_point([ray(KS[cam[i]], R[i], p[i], uv[i]) for i in range(len(uv))])
    if X is None:
        return None
    for _ in range(iterations):
        pred, z, J = project_many(cam, R, p, X)
        if np.any(z <= 0.05):
            return None
        r = uv - pred
        n = np.linalg.norm(r, axis=1)
        w = np.where(n <= huber_px, 1.0, huber_px / np.maximum(n, 1e-12))
        H = np.einsum("n,nki,nkj->ij", w, J, J)
        g = np.einsum("n,nki,nk->i", w, J, r)
        if np.linalg.cond(H) > 1e10:
            return None
        dx = np.linalg.solve(H, g)
        X = X + dx
        if np.linalg.norm(dx) < 1e-9 * max(1.0, np.linalg.norm(X)):
            break
    return X


def project_many(cam_of, R, p, X):
    uv = np.zeros((len(R), 2))
    z = np.zeros(len(R))
    J = np.zeros((len(R), 2, 3))
    X = np.broadcast_to(X, (len(R), 3))  # one point, or one per row
    for cam in (0, 1):
        m = cam_of == cam
        if np.any(m):
            uv[m], z[m], J[m] = project(KS[cam], R[m], p[m], X[m])
    return uv, z, J


KS = [None, None]  # the two cameras' intrinsics, set in main (project_many indexes them)


# ---------------------------------------------------------------- residuals


def observations_at_poses(tracks, run_t):
    """Flat arrays of the observations in frames the run estimated: frame row, track id, cam,
    uv; one row per camera."""
    row_of = {int(t): i for i, t in enumerate(run_t)}
    rows, tid, cam, uv = [], [], [], []
    off = tracks["offsets"]
    for f, t in enumerate(tracks["t_ns"]):
        if int(t) not in row_of:
            continue
        s = slice(off[f], off[f + 1])
        k = row_of[int(t)]
        n = off[f + 1] - off[f]
        rows += [k] * n
        tid += list(tracks["track_id"][s])
        cam += [0] * n
        uv += list(np.stack([tracks["u0"][s], tracks["v0"][s]], -1))
        right = tracks["has_right"][s] != 0
        m = int(right.sum())
        rows += [k] * m
        tid += list(tracks["track_id"][s][right])
        cam += [1] * m
        uv += list(np.stack([tracks["u1"][s][right], tracks["v1"][s][right]], -1))
    return np.array(rows), np.array(tid), np.array(cam), np.array(uv).reshape(-1, 2)


def exp_so3(w):
    theta = np.linalg.norm(w)
    W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    if theta < 1e-12:
        return np.eye(3) + W
    return np.eye(3) + math.sin(theta) / theta * W + (1 - math.cos(theta)) / theta**2 * W @ W


def landmarks(obs, cams):
    """Each track's landmark at the cameras' poses; per track (a, b, X) over the sorted rows."""
    rows, tid, cam, uv = obs
    starts = np.flatnonzero(np.r_[True, tid[1:] != tid[:-1]])
    out = []
    for a, b in zip(starts, np.r_[starts[1:], len(tid)]):
        if b - a < 3:  # two pixels fit any point exactly: no residual to measure
            continue
        c, k = cam[a:b], rows[a:b]
        R = np.where(c[:, None, None] == 0, cams[0][0][k], cams[1][0][k])
        p = np.where(c[:, None] == 0, cams[0][1][k], cams[1][1][k])
        X = triangulate(c, R, p, uv[a:b])
        if X is not None and np.all(project_many(c, R, p, X)[1] > 0.05):
            out.append((a, b, X))
    return out


def frame_cost(obs, sel, X, rig, R_w_b, p_w_b, huber_px=1.0):
    """Huber-weighted residuals of one frame's pixels at body pose (R_w_b, p_w_b)."""
    _, _, cam, uv = obs
    cams = rig.cameras(R_w_b[None], p_w_b[None], "vio")
    pred, _, _ = project_many(cam[sel], np.array([cams[c][0][0] for c in cam[sel]]),
                              np.array([cams[c][1][0] for c in cam[sel]]), X)
    r = uv[sel] - pred
    n = np.linalg.norm(r, axis=1, keepdims=True)
    return r * np.sqrt(np.where(n <= huber_px, 1.0, huber_px / np.maximum(n, 1e-12)))


def refine_poses(obs, tracks_X, rig, R_w_b, p_w_b):
    """Each frame's body pose refined on its pixels with the landmarks held (Gauss-Newton,
    central-difference Jacobian): removes the per-frame pose error of the ground truth (Vicon
    noise, timing), which would otherwise show up as a residual common to every track."""
    rows = obs[0]
    X = np.full((len(rows), 3), np.nan)
    for a, b, x in tracks_X:
        X[a:b] = x
    R_new, p_new = R_w_b.copy(), p_w_b.copy()
    for k in range(len(R_w_b)):
        sel = np.flatnonzero((rows == k) & np.isfinite(X[:, 0]))
        if len(sel) < 10:
            continue
        for _ in range(3):
            def f(d):
                return frame_cost(obs, sel, X[sel], rig, R_new[k] @ exp_so3(d[:3]),
                                  p_new[k] + d[3:]).ravel()
            r0 = f(np.zeros(6))
            J = np.stack([(f(h) - f(-h)) / 2e-6 for h in 1e-6 * np.eye(6)], -1)
            d = -np.linalg.lstsq(J, r0, rcond=None)[0]
            R_new[k], p_new[k] = R_new[k] @ exp_so3(d[:3]), p_new[k] + d[3:]
    return R_new, p_new


def track_residuals(tracks, run, rig, refine):
    """Per residual row (cam0, and cam1 where matched): track id, frame row, camera, residual
    (2, scaled by sqrt(m/(m-3)) for the 3 fitted landmark dof of a track with m coordinates);
    per track: its depth at the first view. With refine, poses and landmarks alternate (a bundle
    adjustment by blocks, started at the given poses)."""
    run_t, R_w_s, p_w_s, mode = run
    obs = observations_at_poses(tracks, run_t)
    order = np.lexsort((obs[2], obs[0], obs[1]))
    obs = tuple(a[order] for a in obs)
    cams = rig.cameras(R_w_s, p_w_s, mode)
    tracks_X = landmarks(obs, cams)
    for _ in range(refine):
        R_w_s, p_w_s = refine_poses(obs, tracks_X, rig, R_w_s, p_w_s)
        cams = rig.cameras(R_w_s, p_w_s, "vio")
        tracks_X = landmarks(obs, cams)
    rows, tid, cam, uv = obs
    out = {"tid": [], "row": [], "cam": [], "r": []}
    depths = []
    for a, b, X in tracks_X:
        c, k = cam[a:b], rows[a:b]
        R = np.where(c[:, None, None] == 0, cams[0][0][k], cams[1][0][k])
        p = np.where(c[:, None] == 0, cams[0][1][k], cams[1][1][k])
        pred, z, _ = project_many(c, R, p, X)
        out["tid"] += [tid[a]] * (b - a)
        out["row"] += list(k)
        out["cam"] += list(c)
        out["r"] += list(math.sqrt(2 * (b - a) / (2 * (b - a) - 3)) * (uv[a:b] - pred))
        depths.append(z[0])
    res = {key: np.array(v) for key, v in out.items()}
    res["r"] = res["r"].reshape(-1, 2)
    res["depth"] = np.array(depths)
    return res


# ---------------------------------------------------------------- epipolar residuals


def fundamental(rig):
    """F with x1^T F x0 = 0 for pixels x0 of cam0 and x1 of cam1 (the calibration's T_c1_c0)."""
    T = np.linalg.inv(rig.T_b_c1) @ rig.T_b_c0
    R, t = T[:3, :3], T[:3, 3]
    E = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]]) @ R
    Kinv = [np.linalg.inv(np.array([[k[0], 0, k[2]], [0, k[1], k[3]], [0, 0, 1.0]]))
            for k in (rig.K0, rig.K1)]
    return Kinv[1].T @ E @ Kinv[0]


def sampson(F, uv0, uv1):
    """Signed Sampson distance of each stereo pair: the first-order distance of (uv0, uv1) to
    the epipolar constraint in the 4-d space of both pixels, so with independent noise sigma per
    pixel coordinate it is ~ N(0, sigma^2) — one noise component per pair, needing no depth."""
    x0 = np.c_[uv0, np.ones(len(uv0))]
    x1 = np.c_[uv1, np.ones(len(uv1))]
    l1 = x0 @ F.T  # epipolar lines in cam1
    l0 = x1 @ F    # in cam0
    e = np.sum(x1 * l1, axis=1)
    return e / np.sqrt(l1[:, 0]**2 + l1[:, 1]**2 + l0[:, 0]**2 + l0[:, 1]**2)


def epipolar_stats(tracks, run_t, rig, outlier_px=5.0):
    """Sampson residuals of every stereo match in the run's frames (every frame, not only the
    multi-view tracks): their median (a calibration offset), robust sigma and Student-t fit
    about the median, below outlier_px."""
    keep = set(int(t) for t in run_t)
    off = tracks["offsets"]
    uv0, uv1 = [], []
    for f, t in enumerate(tracks["t_ns"]):
        if int(t) not in keep:
            continue
        s = slice(off[f], off[f + 1])
        m = tracks["has_right"][s] != 0
        uv0.append(np.stack([tracks["u0"][s][m], tracks["v0"][s][m]], -1))
        uv1.append(np.stack([tracks["u1"][s][m], tracks["v1"][s][m]], -1))
    d = sampson(fundamental(rig), np.concatenate(uv0), np.concatenate(uv1))
    med = float(np.median(d))
    inl = d[np.abs(d - med) <= outlier_px] - med
    return {"n": int(d.size), "median_px": med, "abs_px": quantiles(np.abs(d - med)),
            "robust_sigma_px": float(1.4826 * np.median(np.abs(d - med))),
            "outlier_share": float(np.mean(np.abs(d - med) > outlier_px)),
            "student_t": student_t_fit(inl)}


# ---------------------------------------------------------------- statistics


def quantiles(x, qs=(0.5, 0.9, 0.95, 0.99, 0.999)):
    return {f"q{q * 100:g}": float(np.quantile(x, q)) for q in qs}


def distribution(x):
    x = np.asarray(x, dtype=float)
    return {"n": int(x.size), "mean": float(x.mean()), "min": float(x.min()),
            **quantiles(x, (0.1, 0.25, 0.5, 0.75, 0.9)), "max": float(x.max())}


def student_t_fit(coords):
    """Maximum-likelihood Student-t (location 0) against a Gaussian of the same data."""
    nu, _, scale = sstats.t.fit(coords, floc=0)
    ll_t = float(np.sum(sstats.t.logpdf(coords, nu, 0, scale)))
    sigma = float(np.sqrt(np.mean(coords**2)))
    ll_g = float(np.sum(sstats.norm.logpdf(coords, 0, sigma)))
    return {"nu": float(nu), "scale_px": float(scale), "gaussian_sigma_px": sigma,
            "loglik_t": ll_t, "loglik_gaussian": ll_g, "n": int(coords.size)}


def outlier_mask(res, outlier_px):
    """Per observation (frame row, track): does its cam0 or cam1 residual exceed outlier_px."""
    norm = np.linalg.norm(res["r"], axis=1)
    key = res["tid"] * 1_000_003 + res["row"]
    bad_keys = set(key[norm > outlier_px].tolist())
    return np.array([k in bad_keys for k in key]), norm


def residual_stats(res, outlier_px):
    bad, norm = outlier_mask(res, outlier_px)
    cam0 = res["cam"] == 0
    inl = res["r"][~bad].ravel()
    obs_keys = np.unique(res["tid"][cam0] * 1_000_003 + res["row"][cam0])
    bad_obs = np.unique((res["tid"] * 1_000_003 + res["row"])[bad])
    return {
        "coordinate_abs_px": quantiles(np.abs(res["r"].ravel())),
        "norm_px": quantiles(norm),
        "robust_sigma_px": float(1.4826 * np.median(np.abs(res["r"].ravel()))),
        "excess_kurtosis_all": float(sstats.kurtosis(res["r"].ravel())),
        "excess_kurtosis_inliers": float(sstats.kurtosis(inl)),
        "student_t_inliers": student_t_fit(inl),
        "outlier_px": outlier_px,
        "outlier_share": float(len(bad_obs) / max(len(obs_keys), 1)),
        "outlier_norm_px": quantiles(norm[norm > outlier_px], (0.1, 0.5, 0.9))
        if np.any(norm > outlier_px) else {},
        "n_observations": int(len(obs_keys)),
        "n_residual_rows": int(len(norm)),
    }


def frame_numbers(t_ns):
    """Camera-frame number of each frame (0 at the first): the shortest gap is one frame, a longer
    gap counts round(gap / shortest) frames, so lags are camera frames also on keyframes."""
    gaps = np.diff(np.asarray(t_ns, dtype=np.int64))
    if len(gaps) == 0:
        return np.zeros(len(t_ns), dtype=np.int64)
    return np.r_[0, np.cumsum(np.maximum(np.round(gaps / gaps.min()), 1))].astype(np.int64)


def drift_stats(res, frame_no, outlier_px, max_lag=20):
    """Variogram of a track's cam0 inlier residual: E[(r(k+L) - r(k))^2] per coordinate against
    the lag L in camera frames, fitted by 2 s_w^2 + q L (least squares over L = 1..max_lag)."""
    bad, _ = outlier_mask(res, outlier_px)
    m = (res["cam"] == 0) & ~bad
    tid, row, r = res["tid"][m], frame_no[res["row"][m]], res["r"][m]
    sums = np.zeros(max_lag + 1)
    counts = np.zeros(max_lag + 1)
    for t in np.unique(tid):
        sel = tid == t
        k, rr = row[sel], r[sel]
        series = np.full((k.max() - k.min() + 1, 2), np.nan)
        series[k - k.min()] = rr
        for lag in range(1, min(max_lag, len(series) - 1) + 1):
            d = series[lag:] - series[:-lag]
            d = d[~np.isnan(d).any(axis=1)]
            sums[lag] += np.sum(d**2) / 2
            counts[lag] += len(d)
    lags = np.flatnonzero(counts > 0)
    lags = lags[lags > 0]
    gamma = sums[lags] / counts[lags]
    A = np.stack([np.ones(len(lags)), lags], -1)
    (c, q), *_ = np.linalg.lstsq(A, gamma, rcond=None)
    return {"lags": lags.tolist(), "mean_sq_diff_px2": gamma.tolist(),
            "white_sigma_px": float(math.sqrt(max(c, 0) / 2)),
            "walk_step_px": float(math.sqrt(max(q, 0))), "walk_q_px2_per_frame": float(q)}


def track_stats(tracks, run_t):
    """Lengths, loss hazard, features per frame and stereo share over the run's frames."""
    keep = set(int(t) for t in run_t)
    off = tracks["offsets"]
    per_frame, stereo, seen = [], 0, {}
    frames = [f for f, t in enumerate(tracks["t_ns"]) if int(t) in keep]
    for i, f in enumerate(frames):
        s = slice(off[f], off[f + 1])
        per_frame.append(off[f + 1] - off[f])
        stereo += int(np.sum(tracks["has_right"][s] != 0))
        for t in tracks["track_id"][s]:
            first, last = seen.get(int(t), (i, i))
            seen[int(t)] = (first, i)
    lengths = np.array([b - a + 1 for a, b in seen.values()])
    ended = sum(1 for _, b in seen.values() if b < len(frames) - 1)
    total = int(np.sum(per_frame))
    continued = total - len(seen)  # frame-to-frame transitions a track survived
    return {
        "frames": len(frames), "tracks": len(seen),
        "features_per_frame": distribution(per_frame),
        "track_length_frames": distribution(lengths),
        "alive_at_last_frame_share": float(1 - ended / max(len(seen), 1)),
        "loss_hazard_per_frame": float(ended / max(total - len(seen), 1)),
        # censored geometric: continuations / (continuations + ends), what the simulator's
        # per-frame survival (1 - loss) times the geometric visibility reproduces
        "continued_share_per_frame": float(continued / max(continued + ended, 1)),
        "stereo_share": float(stereo / max(total, 1)),
    }


def consecutive_tracking(tracks, run_t):
    """Short tracking where the frames are consecutive camera frames (frame number + 1): the share
    of a frame's tracks found again in the next frame, and the features per such frame."""
    frame_no = frame_numbers(run_t)
    index = {int(t): f for f, t in enumerate(tracks["t_ns"])}
    off = tracks["offsets"]
    ids = [set(tracks["track_id"][off[index[int(t)]]:off[index[int(t)] + 1]].tolist())
           for t in run_t]
    pairs = [k for k in range(len(run_t) - 1) if frame_no[k + 1] == frame_no[k] + 1]
    kept = sum(len(ids[k] & ids[k + 1]) for k in pairs)
    total = sum(len(ids[k]) for k in pairs)
    return {"consecutive_pairs": len(pairs), "tracks_at_pair_starts": total,
            "continued_share": float(kept / total) if total else float("nan")}


def consecutive_run(run):
    """The run's frames that have a consecutive camera frame before or after them (keyframes:
    the residuals of tracks across a gap of a second would mix in re-detection errors)."""
    n = frame_numbers(run[0])
    keep = np.r_[False, np.diff(n) == 1] | np.r_[np.diff(n) == 1, False]
    return (run[0][keep], run[1][keep], run[2][keep], run[3])


def path_length(p):
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1))) if len(p) > 1 else 0.0


def gt_frames(tracks, gt_path):
    """The track file's frames inside the ground truth's time span (a run on keyframes is not
    possible: they are not consecutive), for --source NAME TRACKS gt."""
    try:
        gt = np.loadtxt(gzip.open(gt_path, "rt") if gt_path.endswith(".gz") else gt_path, ndmin=2)
    except (OSError, ValueError) as e:
        fail(f"{gt_path}: not a readable TUM trajectory ({e})")
    t0, t1 = np.round(gt[0, 0] * 1e9), np.round(gt[-1, 0] * 1e9)
    t = tracks["t_ns"]
    return t[(t >= t0) & (t <= t1)]


def source_stats(name, tracks_path, run_path, rig, args):
    KS[0], KS[1] = rig.K0, rig.K1
    tracks = read_tracks(tracks_path)
    if run_path == "gt":
        if not args.gt or os.path.basename(args.gt).startswith("poses"):
            fail(f"--source {name} {tracks_path} gt: needs --gt with a TUM trajectory")
        run = (gt_frames(tracks, args.gt), None, None, "vio")
    else:
        run = read_run(run_path)
    if args.gt:  # the ground truth's body poses at the run's frames replace its estimate
        read = read_kitti_poses if os.path.basename(args.gt).startswith("poses") else read_gt_poses
        run = (run[0], *read(args.gt, run[0]), "vio")
    outlier_px = args.outlier_px
    tracked = consecutive_run(run) if args.consecutive_residuals else run
    res = track_residuals(tracks, tracked, rig, args.refine_poses)
    if len(res["tid"]) == 0:
        fail(f"{tracks_path}: no track with three or more pixels at the run's frames")
    out = {"source": name, "tracks_file": tracks_path, "run_file": run_path,
           "poses": f"the ground truth ({args.gt})" if args.gt else "the run's per-frame estimate",
           "pose_refinement_rounds": args.refine_poses,
           "residual_frames": len(tracked[0]), "gt_path_m": path_length(run[2])}
    out.update(track_stats(tracks, run[0]))
    out["depth_m"] = distribution(res["depth"])
    out["residuals"] = residual_stats(res, outlier_px)
    out["drift"] = drift_stats(res, frame_numbers(tracked[0]), outlier_px)
    out["epipolar"] = epipolar_stats(tracks, run[0], rig)
    out["consecutive_tracking"] = consecutive_tracking(tracks, run[0])
    return out


# ---------------------------------------------------------------- the realistic profile

IDEAL = {"loss_probability": 0.03, "stereo_failure_probability": 0.03}  # feature_tracker.h


def t_exceedance(nu, scale, threshold, n=400000):
    """P(|(x, y)| > threshold) for independent Student-t coordinates (Monte Carlo, fixed seed)."""
    rng = np.random.default_rng(12345)
    xy = scale * rng.standard_t(nu, size=(n, 2))
    return float(np.mean(np.hypot(xy[:, 0], xy[:, 1]) > threshold))


def read_loss_probability(path):
    """[tracking] loss_probability of a profile file (tomllib is Python 3.11+: a regex on the
    file this script writes)."""
    try:
        text = open(path, encoding="utf-8").read()
    except OSError as e:
        fail(f"{path}: cannot read ({e.strerror})")
    m = re.search(r"^loss_probability\s*=\s*([0-9.eE+-]+)", text, re.M)
    if not m:
        fail(f"{path}: expected a line loss_probability = NUMBER")
    return float(m.group(1))


def realistic_profile(real, ideal, clip_motion_m, min_motion_m):
    """The simulator's `realistic` parameters: real's measurements, relative to the ideal
    simulation of the same frames where the simulator's geometry decides (cells, stereo)."""
    res = real["residuals"]
    fit = res["student_t_inliers"]
    stereo = real["stereo_share"]
    p_t = t_exceedance(fit["nu"], fit["scale_px"], res["outlier_px"])
    p_t_obs = 1 - (1 - p_t) ** (1 + stereo)  # cam0, and cam1 where matched
    geometric_stereo = ideal["stereo_share"] / (1 - IDEAL["stereo_failure_probability"])
    fill = (real["features_per_frame"]["q50"] / ideal["features_per_frame"]["q50"])
    moving = clip_motion_m >= min_motion_m
    # The simulator's survival is (1 - loss) times the geometric one (a landmark leaving the view),
    # which the ideal simulation of the same frames measures: its continued share over 1 - 0.03.
    geometric_survival = ideal["continued_share_per_frame"] / (1 - IDEAL["loss_probability"])
    loss = 1 - real["continued_share_per_frame"] / max(geometric_survival, 1e-9)
    onorm = res["outlier_norm_px"]
    return {
        "noise": {"nu": fit["nu"], "scale_px": fit["scale_px"]},
        "drift": {"step_px": real["drift"]["walk_step_px"]},
        "outliers": {"probability": max(res["outlier_share"] - p_t_obs, 0.0),
                     "min_px": max(onorm.get("q10", 5.0), res["outlier_px"]),
                     "max_px": max(onorm.get("q90", 20.0), res["outlier_px"] + 1)},
        "tracking": {
            "loss_probability": min(max(loss, 0.0), 0.95) if moving
            else IDEAL["loss_probability"],
            "stereo_failure_probability": min(max(1 - stereo / geometric_stereo, 0.0), 0.95),
            "cell_fill_probability": min(fill, 1.0),
        },
        "notes": {"t_exceedance_per_observation": p_t_obs, "clip_motion_m": clip_motion_m,
                  "loss_measured": moving},
    }


def keyframe_origins(real, ideal, loss_from):
    """The origin of each number of a profile measured on keyframes (--loss-from), for its
    comments: what was measured on which frames, and what was taken from elsewhere."""
    res, epi, run = real["residuals"], real["epipolar"], real["consecutive_tracking"]
    geometric = ideal["consecutive_tracking"]["continued_share"] / (1 - IDEAL["loss_probability"])
    return {
        "noise": f"Student-t fit to the inlier residuals of the {real['residual_frames']} "
                 f"consecutive frames ({res['n_observations']} observations); the stereo "
                 f"matches' Sampson residuals of all {real['frames']} frames give "
                 f"nu {epi['student_t']['nu']:.3g}, scale {epi['student_t']['scale_px']:.3g} px",
        "drift": f"variogram over the {real['residual_frames']} consecutive frames",
        "outliers": f"residuals above {res['outlier_px']:g} px in the consecutive frames",
        "loss": f"{loss_from} (KITTI 06 under motion): keyframes cannot measure track loss; "
                f"their consecutive frames give {1 - run['continued_share'] / geometric:.3g} "
                f"({run['tracks_at_pair_starts']} tracks, not used)",
        "stereo": f"real stereo share {real['stereo_share']:.3g} of {real['frames']} frames / "
                  f"the ideal simulation's geometric {ideal['stereo_share']:.3g} / 0.97",
        "fill": "real / ideal features per frame ({:.0f} / {:.0f})".format(
            real["features_per_frame"]["q50"], ideal["features_per_frame"]["q50"]),
    }


def profile_toml(profile, command, out):
    if "origins" in profile:
        return keyframe_profile_toml(profile, command, out)
    n, d, o, t = (profile[k] for k in ("noise", "drift", "outliers", "tracking"))
    notes = profile["notes"]
    loss_note = ("real continued share / the ideal simulation's geometric one"
                 if notes["loss_measured"] else
                 f"the ideal value: the clip moves {notes['clip_motion_m']:.3f} m, too little "
                 "to measure track loss under motion")
    return f"""# The simulator's `realistic` profile (docs/design.md §5, core/sim/sim_profile.h), calibrated
# on real frames. Written by tools/scripts/frontend_stats.py; do not edit by hand:
#   {command}
# Measured on the front-end's tracks at the ground-truth poses of the run's frames, refined with the
# landmarks (bundle adjustment by blocks); {out}/frontend_stats.md has every
# measurement and the ideal simulation of the same frames beside it.

[noise]  # per pixel coordinate: scale * Student-t(nu), fitted to the inlier residuals
nu = {n['nu']:.6g}
scale_px = {n['scale_px']:.6g}

[drift]  # each track's pixel offset walks by step_px * N(0, 1) per coordinate and frame
step_px = {d['step_px']:.6g}

[outliers]  # wrong associations: residual above the threshold, minus the t's own tail
# ({notes['t_exceedance_per_observation']:.4g} per observation); displacement uniform in [min, max]
probability = {o['probability']:.6g}
min_px = {o['min_px']:.6g}
max_px = {o['max_px']:.6g}

[tracking]
loss_probability = {t['loss_probability']:.6g}  # {loss_note}
stereo_failure_probability = {t['stereo_failure_probability']:.6g}  # real stereo share
cell_fill_probability = {t['cell_fill_probability']:.6g}  # real / ideal features per frame
"""


def keyframe_profile_toml(profile, command, out):
    n, d, o, t, why = (profile[k] for k in ("noise", "drift", "outliers", "tracking", "origins"))
    return f"""# The simulator's `realistic-motion` profile of EuRoC / TUM-VI runs (docs/design.md §5,
# core/sim/sim_profile.h), calibrated on real stereo keyframes under motion. Written by
# tools/scripts/frontend_stats.py; do not edit by hand:
#   {command}
# Measured on the front-end's tracks at the ground-truth poses of the frames, refined with the
# landmarks (bundle adjustment by blocks); {out}/frontend_stats.md has every
# measurement and the ideal simulation of the same frames beside it.

[noise]  # per pixel coordinate: scale * Student-t(nu)
# {why['noise']}
nu = {n['nu']:.6g}
scale_px = {n['scale_px']:.6g}

[drift]  # each track's pixel offset walks by step_px * N(0, 1) per coordinate and frame
# {why['drift']}
step_px = {d['step_px']:.6g}

[outliers]  # wrong associations: {why['outliers']}, minus the t's own tail
# ({profile['notes']['t_exceedance_per_observation']:.4g} per observation); displacement uniform in [min, max]
probability = {o['probability']:.6g}
min_px = {o['min_px']:.6g}
max_px = {o['max_px']:.6g}

[tracking]
# loss: {why['loss']}
loss_probability = {t['loss_probability']:.6g}
# stereo: {why['stereo']}
stereo_failure_probability = {t['stereo_failure_probability']:.6g}
# fill: {why['fill']}
cell_fill_probability = {t['cell_fill_probability']:.6g}
"""


# ---------------------------------------------------------------- output


def md_row(label, values, fmt="{:.3g}"):
    return f"| {label} | " + " | ".join(
        fmt.format(v) if isinstance(v, (int, float)) else str(v) for v in values) + " |"


def markdown(sources, command, profile):
    names = [s["source"] for s in sources]
    g = lambda f: [f(s) for s in sources]  # noqa: E731
    r = lambda s: s["residuals"]  # noqa: E731
    lines = [
        "# Front-end statistics at the converged estimate", "",
        f"`{command}`", "",
        "Residuals r = uv − π(T_w_c⁻¹ p_w) of every pixel (cam0, and cam1 where matched) at the "
        f"converged estimate: poses from {sources[0]['poses']}, refined per frame alternately "
        "with the landmarks (each triangulated by Huber-IRLS, 1 px; residuals scaled by "
        "√(m/(m−3)) for the 3 fitted landmark dof). Outlier: cam0 or "
        f"cam1 residual norm above {sources[0]['residuals']['outlier_px']:g} px. Drift: "
        "E[(r(k+L) − r(k))²] per coordinate = 2 s_w² + q L over lags L = 1..20 (cam0 inliers).",
        "", "| measure | " + " | ".join(names) + " |", "|---|" + "---:|" * len(names),
        md_row("frames / tracks", g(lambda s: f"{s['frames']} / {s['tracks']}")),
        md_row("features per frame, median (min–max)", g(lambda s: "{:.0f} ({:.0f}–{:.0f})".format(
            s["features_per_frame"]["q50"], s["features_per_frame"]["min"],
            s["features_per_frame"]["max"]))),
        md_row("stereo share", g(lambda s: s["stereo_share"])),
        md_row("track length [frames], median (p10–p90)", g(lambda s: "{:.0f} ({:.0f}–{:.0f})".format(
            s["track_length_frames"]["q50"], s["track_length_frames"]["q10"],
            s["track_length_frames"]["q90"]))),
        md_row("tracks alive at the last frame", g(lambda s: s["alive_at_last_frame_share"])),
        md_row("loss hazard per frame", g(lambda s: s["loss_hazard_per_frame"])),
        md_row("continued share per frame", g(lambda s: s["continued_share_per_frame"])),
        md_row("depth [m], median (p10–p90)", g(lambda s: "{:.2f} ({:.2f}–{:.2f})".format(
            s["depth_m"]["q50"], s["depth_m"]["q10"], s["depth_m"]["q90"]))),
        md_row("\\|r\\| per coordinate [px]: p50 / p90 / p95 / p99 / p99.9", g(lambda s: " / ".join(
            f"{v:.3g}" for v in r(s)["coordinate_abs_px"].values()))),
        md_row("robust σ (1.4826 MAD) [px]", g(lambda s: r(s)["robust_sigma_px"])),
        md_row("excess kurtosis, all / inliers", g(lambda s: "{:.3g} / {:.3g}".format(
            r(s)["excess_kurtosis_all"], r(s)["excess_kurtosis_inliers"]))),
        md_row("Student-t fit (inliers): ν, scale [px]", g(lambda s: "{:.3g}, {:.3g}".format(
            r(s)["student_t_inliers"]["nu"], r(s)["student_t_inliers"]["scale_px"]))),
        md_row("log-likelihood t − Gaussian", g(lambda s: r(s)["student_t_inliers"]["loglik_t"]
                                                 - r(s)["student_t_inliers"]["loglik_gaussian"])),
        md_row("outlier share", g(lambda s: r(s)["outlier_share"])),
        md_row("drift: white σ_w [px], walk step [px/frame]", g(lambda s: "{:.3g}, {:.3g}".format(
            s["drift"]["white_sigma_px"], s["drift"]["walk_step_px"]))),
        md_row("observations measured", g(lambda s: r(s)["n_observations"]), "{}"),
        md_row("frames of the residuals", g(lambda s: s["residual_frames"]), "{}"),
        md_row("stereo matches' Sampson distance: n, median [px]", g(lambda s: "{}, {:.3g}".format(
            s["epipolar"]["n"], s["epipolar"]["median_px"]))),
        md_row("Sampson about the median: robust σ [px], t ν, scale [px]", g(
            lambda s: "{:.3g}, {:.3g}, {:.3g}".format(
                s["epipolar"]["robust_sigma_px"], s["epipolar"]["student_t"]["nu"],
                s["epipolar"]["student_t"]["scale_px"]))),
        md_row("consecutive frames: pairs, continued share", g(lambda s: "{}, {:.3g}".format(
            s["consecutive_tracking"]["consecutive_pairs"],
            s["consecutive_tracking"]["continued_share"]))),
    ]
    if profile is not None:
        lines += ["", "## The `realistic` profile written from the first column", "", "```toml",
                  profile.strip(), "```"]
    return "\n".join(lines) + "\n"


def clip_motion(run_path):
    with h5py.File(run_path, "r") as f:
        p = f["frames/p_gt"][:]
    p = p[np.isfinite(p).all(axis=1)]
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1))) if len(p) > 1 else 0.0


def write_text(path, text):
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", nargs=3, action="append", required=True,
                    metavar=("NAME", "TRACKS_H5", "RUN_H5"),
                    help="a track file and the results file of a run on it (repeatable; the "
                         "profile is calibrated on the first against the second)")
    ap.add_argument("--calib", required=True,
                    help="EuRoC mav0 folder (cam0/1 sensor.yaml) or KITTI folder (calib.txt)")
    ap.add_argument("--right-cx-shift", type=float, default=0.0, metavar="PX",
                    help="add PX to cam1's cx (every predicted disparity) for the first source "
                         "(the real frames), e.g. a measured rectification bias "
                         "(tools/scripts/stereo_bias.py)")
    ap.add_argument("--gt", help="TUM ground truth of the body, or a KITTI poses.txt (times.txt "
                    "beside it): evaluate at its poses instead of the run's estimate")
    ap.add_argument("--refine-poses", type=int, default=3, metavar="N",
                    help="alternations of per-frame pose refinement and triangulation (0: none)")
    ap.add_argument("--consecutive-residuals", action="store_true",
                    help="measure residuals, outliers and drift only on frames with a consecutive "
                         "camera frame beside them (keyframes); the rest on every frame")
    ap.add_argument("--loss-from", metavar="PROFILE_TOML",
                    help="take [tracking] loss_probability from this profile (frames that cannot "
                         "measure track loss, e.g. keyframes: the KITTI 06 value)")
    ap.add_argument("--outlier-px", type=float, default=5.0)
    ap.add_argument("--min-motion-m", type=float, default=0.5,
                    help="below this ground-truth path length the loss hazard is not measured")
    ap.add_argument("--out", required=True, help="folder for frontend_stats.{md,json}")
    ap.add_argument("--profile-out", help="write the realistic profile (TOML) here")
    return ap.parse_args()


def main():
    args = parse_args()
    # The shift corrects the real frames' rectification; simulated tracks use the exact one.
    rigs = [Rig(args.calib, args.right_cx_shift if i == 0 else 0.0)
            for i in range(len(args.source))]
    # Inputs by file name (they live in a scratch folder; results/frontend_stats/README.md makes
    # them), repository paths as given.
    sources = {p for s in args.source for p in s[1:]}
    command = "tools/scripts/frontend_stats.py " + " ".join(
        os.path.basename(a) if a in sources else a for a in sys.argv[1:])
    sources = [source_stats(n, t, r, rig, args) for (n, t, r), rig in zip(args.source, rigs)]
    profile_text = None
    if args.profile_out:
        if len(sources) < 2:
            print("frontend_stats.py: --profile-out needs two sources (real, ideal)",
                  file=sys.stderr)
            sys.exit(2)
        motion = (sources[0]["gt_path_m"] if args.source[0][2] == "gt"
                  else clip_motion(args.source[0][2]))
        profile = realistic_profile(sources[0], sources[1], motion, args.min_motion_m)
        if args.loss_from:
            profile["tracking"]["loss_probability"] = read_loss_probability(args.loss_from)
            profile["origins"] = keyframe_origins(sources[0], sources[1], args.loss_from)
        sources[0]["realistic_profile"] = profile
        profile_text = profile_toml(profile, command, args.out)
        write_text(args.profile_out, profile_text)
    os.makedirs(args.out, exist_ok=True)
    write_text(os.path.join(args.out, "frontend_stats.json"),
               json.dumps({"command": command, "sources": sources}, indent=1) + "\n")
    md = markdown(sources, command, profile_text)
    write_text(os.path.join(args.out, "frontend_stats.md"), md)
    print(md)


if __name__ == "__main__":
    main()
