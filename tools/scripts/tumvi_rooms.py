#!/usr/bin/python3
"""Issue #40 §1: why our TUM-VI room ATEs lie above the paper's — the measurements on the shipped
ground truth and IMU.

  stats SEQ...            per sequence (shipped names, e.g. euroc/V1_01_easy tumvi/room1): the
                          ground truth's span, rate and gaps (> 3 sample periods), the share of
                          camera frames inside a gap, the angular speed and speed over 0.1 s
                          (median / p90, from the ground truth) and the real gyro's angular speed
                          where the IMU ships; a Markdown table.
  smooth SEQ OUT --sigma-ms S
                          a copy of the shipped sequence's folder whose ground truth (gt_asl.csv)
                          is smoothed by a Gaussian of S ms along time within each gap-free
                          stretch (positions; quaternions averaged and normalized), with the rms
                          change it made: the simulation then runs along a trajectory without the
                          mocap's sample-to-sample noise (marglab run --dataset
                          OUT/<family>/<name>_smooth<S>ms).
  imu-offset SEQ...       per sequence, where in time the real gyro's samples lie against the
                          ground truth: over 50 ms windows, the ground truth's rotation
                          log(R_a^T R_b) against the gyro integrated over [a + τ, b + τ] (samples
                          read as instantaneous, linear in between), the τ of least rms residual and
                          the residual at τ = -2.5, 0, +2.5 ms (half the 200 Hz IMU's period).
  shift-imu SEQ OUT --ms D
                          a copy of the shipped sequence's folder whose IMU timestamps are moved by
                          D ms (OUT/<family>/<name>_imu<D>ms): with D = -2.5 the estimator's hold
                          [t_k, t_k + Δt) of the real IMU is centred on each sample's instant, the
                          real-IMU counterpart of sim.imu_sample_time = "midpoint".
"""

import argparse
import gzip
import os
import shutil
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from frontend_stats import quat_to_R  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def load(seq, name):
    path = os.path.join(ROOT, "datasets", seq, name)
    try:
        return np.loadtxt(gzip.open(path, "rt"), delimiter="," if "csv" in name else None,
                          comments="#", ndmin=2)
    except (OSError, ValueError) as e:
        sys.exit(f"tumvi_rooms.py: {path}: cannot read ({e})")


def motion_row(seq):
    gt = load(seq, "gt_tum.txt.gz")
    cam = load(seq, "cam0_timestamps_ns.txt.gz")[:, 0] * 1e-9
    t, dt = gt[:, 0], np.diff(gt[:, 0])
    period = np.median(dt)
    gap = dt > 3 * period
    i = np.clip(np.searchsorted(t, cam[(cam >= t[0]) & (cam <= t[-1])]), 1, len(t) - 1)
    in_gap = np.mean(t[i] - t[i - 1] > 3 * period)
    g = np.arange(t[0], t[-1], 0.1)  # 0.1 s steps where both ends lie in gap-free stretches
    j = np.clip(np.searchsorted(t, g), 1, len(t) - 1)
    j = j[(t[j] - t[j - 1]) < 3 * period]
    R, p, tj = quat_to_R(gt[j, 4:8]), gt[j, 1:4], t[j]
    ok = np.diff(tj) < 0.15
    dR = np.einsum("nji,njk->nik", R[:-1], R[1:])
    ang = np.degrees(np.arccos(np.clip((np.trace(dR, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    ang, v = (ang / np.diff(tj))[ok], (np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(tj))[ok]
    gyro = "–"
    if os.path.exists(os.path.join(ROOT, "datasets", seq, "imu0_asl.csv.gz")):
        imu = load(seq, "imu0_asl.csv.gz")
        w = np.degrees(np.linalg.norm(imu[(imu[:, 0] * 1e-9 > t[0]) & (imu[:, 0] * 1e-9 < t[-1]),
                                          1:4], axis=1))
        gyro = f"{np.median(w):.0f} / {np.quantile(w, 0.9):.0f}"
    return (f"| {seq} | {t[-1] - t[0]:.0f} | {1 / period:.0f} | {gap.sum()} ({dt[gap].sum():.1f} s, "
            f"longest {dt.max():.2f} s) | {in_gap:.3f} | {np.median(ang):.0f} / "
            f"{np.quantile(ang, 0.9):.0f} | {gyro} | {np.median(v):.2f} / {np.quantile(v, 0.9):.2f} |")


def stats(seqs):
    print("| sequence | GT span [s] | GT rate [Hz] | GT gaps > 3 periods (total, longest) | "
          "camera frames in a gap | angular speed, GT 0.1 s: median / p90 [°/s] | gyro: median / "
          "p90 [°/s] | speed median / p90 [m/s] |")
    print("|---|---:|---:|---|---:|---:|---:|---:|")
    for seq in seqs:
        print(motion_row(seq))


def smooth_stretch(t, x, sigma_s):
    """Gaussian smoothing of the rows of x along the times t (one gap-free stretch)."""
    out = np.empty_like(x)
    for k in range(len(t)):
        m = np.abs(t - t[k]) <= 3 * sigma_s
        w = np.exp(-0.5 * ((t[m] - t[k]) / sigma_s) ** 2)
        out[k] = w @ x[m] / w.sum()
    return out


def smooth(seq, out, sigma_ms):
    gt = load(seq, "gt_asl.csv.gz")  # t_ns, p (3), q w x y z
    t = gt[:, 0] * 1e-9
    q = gt[:, 4:8].copy()
    q[np.r_[False, np.cumsum(np.sum(q[1:] * q[:-1], axis=1) < 0) % 2 == 1]] *= -1  # one hemisphere
    cuts = np.r_[0, np.flatnonzero(np.diff(t) > 3 * np.median(np.diff(t))) + 1, len(t)]
    new = gt.copy()
    for a, b in zip(cuts[:-1], cuts[1:]):
        new[a:b, 1:4] = smooth_stretch(t[a:b], gt[a:b, 1:4], sigma_ms * 1e-3)
        qs = smooth_stretch(t[a:b], q[a:b], sigma_ms * 1e-3)
        new[a:b, 4:8] = qs / np.linalg.norm(qs, axis=1, keepdims=True)
    dp = np.linalg.norm(new[:, 1:4] - gt[:, 1:4], axis=1)
    dq = np.degrees(2 * np.arccos(np.clip(np.abs(np.sum(new[:, 4:8] * q, axis=1)), 0, 1)))
    family = os.path.dirname(seq)  # the loader wants <family>/<name> next to <family>/calib
    folder = os.path.join(out, family, os.path.basename(seq) + f"_smooth{sigma_ms:g}ms")
    shutil.copytree(os.path.join(ROOT, "datasets", seq), folder)
    if not os.path.exists(os.path.join(out, family, "calib")):
        shutil.copytree(os.path.join(ROOT, "datasets", family, "calib"),
                        os.path.join(out, family, "calib"))
    os.remove(os.path.join(folder, "gt_tum.txt.gz"))
    with gzip.open(os.path.join(folder, "gt_asl.csv.gz"), "wt") as f:
        f.write("#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], "
                "q_RS_y [], q_RS_z []\n")
        for row in new:
            f.write(f"{int(row[0])}," + ",".join(f"{v:.10f}" for v in row[1:]) + "\n")
    print(f"{folder}: sigma {sigma_ms:g} ms, {len(cuts) - 1} stretches; the smoothing moved the "
          f"positions by {1e3 * np.sqrt(np.mean(dp**2)):.2f} mm rms and the attitudes by "
          f"{np.sqrt(np.mean(dq**2)):.3f} deg rms")


def so3_log(R):
    """Rotation vectors of the rotation matrices R (n, 3, 3), angles below π."""
    theta = np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1, 1))
    scale = np.where(theta < 1e-9, 0.5, theta / (2 * np.sin(np.maximum(theta, 1e-9))))
    v = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], -1)
    return v * scale[:, None]


def imu_offset_row(seq, window_s=0.05, step_ms=0.25):
    gt, imu = load(seq, "gt_tum.txt.gz"), load(seq, "imu0_asl.csv.gz")
    t, R = gt[:, 0], quat_to_R(gt[:, 4:8])
    period = np.median(np.diff(t))
    n = int(round(window_s / period))
    a = np.arange(0, len(t) - n, n)
    ti, dt_fine = imu[:, 0] * 1e-9, 2.5e-4
    a = a[((t[a + n] - t[a]) < 1.5 * n * period) & (t[a] > ti[0] + 0.05) & (t[a + n] < ti[-1] - 0.05)]
    rot_gt = so3_log(np.einsum("nji,njk->nik", R[a], R[a + n]))  # windows without a GT gap
    fine = np.arange(ti[0], ti[-1], dt_fine)
    g = np.stack([np.interp(fine, ti, imu[:, 1 + c]) for c in range(3)], -1)
    cum = np.vstack([np.zeros(3), np.cumsum(0.5 * (g[1:] + g[:-1]) * dt_fine, axis=0)])
    taus = np.arange(-10, 10 + step_ms / 2, step_ms)
    rms = []
    for tau in taus * 1e-3:
        d = np.stack([np.interp(t[a + n] + tau, fine, cum[:, c]) - np.interp(t[a] + tau, fine, cum[:, c])
                      for c in range(3)], -1) - rot_gt
        d -= d.mean(0)  # the gyro bias over a window
        rms.append(np.sqrt(np.mean(np.sum(d**2, 1))))
    rms = np.array(rms)
    k = int(np.clip(np.argmin(rms), 1, len(rms) - 2))
    y0, y1, y2 = rms[k - 1:k + 2]
    best = taus[k] + step_ms * (y0 - y2) / (2 * (y0 - 2 * y1 + y2))  # parabola through the minimum
    at = [1e3 * rms[np.argmin(abs(taus - x))] for x in (-2.5, 0, 2.5)]
    return (f"| {seq} | {len(a)} | {best:+.2f} | {at[0]:.2f} / {at[1]:.2f} / {at[2]:.2f} |")


def imu_offset(seqs):
    print("| sequence | 50 ms windows | gyro sample stamped t = rate at t + τ: τ [ms] | "
          "rms residual per window at τ = -2.5 / 0 / +2.5 ms [mrad] |")
    print("|---|---:|---:|---:|")
    for seq in seqs:
        print(imu_offset_row(seq))


def shift_imu(seq, out, ms):
    family = os.path.dirname(seq)
    folder = os.path.join(out, family, os.path.basename(seq) + f"_imu{ms:g}ms")
    shutil.copytree(os.path.join(ROOT, "datasets", seq), folder)
    if not os.path.exists(os.path.join(out, family, "calib")):
        shutil.copytree(os.path.join(ROOT, "datasets", family, "calib"),
                        os.path.join(out, family, "calib"))
    shift_ns = int(round(ms * 1e6))
    path = os.path.join(folder, "imu0_asl.csv.gz")
    with gzip.open(path, "rt") as f:
        lines = f.read().splitlines()
    with gzip.open(path, "wt") as f:
        for line in lines:  # integer nanoseconds: a float would round them to 256 ns
            if line.startswith("#") or not line.strip():
                f.write(line + "\n")
                continue
            stamp, rest = line.split(",", 1)
            f.write(f"{int(stamp) + shift_ns},{rest}\n")
    print(f"{folder}: IMU timestamps moved by {ms:g} ms")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="verb", required=True)
    s = sub.add_parser("stats")
    s.add_argument("seqs", nargs="+")
    m = sub.add_parser("smooth")
    m.add_argument("seq")
    m.add_argument("out")
    m.add_argument("--sigma-ms", type=float, default=10.0)
    o = sub.add_parser("imu-offset")
    o.add_argument("seqs", nargs="+")
    h = sub.add_parser("shift-imu")
    h.add_argument("seq")
    h.add_argument("out")
    h.add_argument("--ms", type=float, required=True)
    args = ap.parse_args()
    if args.verb == "stats":
        stats(args.seqs)
    elif args.verb == "imu-offset":
        imu_offset(args.seqs)
    elif args.verb == "shift-imu":
        shift_imu(args.seq, args.out, args.ms)
    else:
        smooth(args.seq, args.out, args.sigma_ms)


if __name__ == "__main__":
    main()
