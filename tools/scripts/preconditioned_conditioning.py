#!/usr/bin/env python3
"""Conditioning of the stored marginalization priors of runs, unscaled and preconditioned
(docs/preconditioned_storage.md, issue #31 §3).

Usage: preconditioned_conditioning.py --out CSV [--plot PNG] RUN.h5 [RUN.h5 ...]

For every prior a run stored (/marg/priors/<k>/H_m: the gauge-free shadow prior, in the variables'
own units; `marglab run --store-prior-every 1` stores every one), in double precision:
  unscaled   H
  jacobi     D H D,   D = diag(2^-round(log2(H_ii)/2))        (the `sqj` storage's scaling)
  block      Pᵀ H P,  P = blockdiag(L_k^-T), H_kk = L_k L_kᵀ  (3×3 blocks; `sqp`)
and of each the eigenvalues λ_1 ≤ … ≤ λ_n. The gauge-free prior has an exact nullspace of the
gauge's dimension g (4 in VIO: x, y, z, yaw; 6 in stereo VO), and a congruence keeps the inertia
(Sylvester), so each scaling has the same g-dimensional nullspace: the condition number reported
is κ = λ_n / λ_{g+1} over the observable directions, and `neg` = λ_1 / λ_n, the most negative
eigenvalue relative to the largest (0 for an exact PSD prior; ε-sized from rounding; below −ε a
prior that a factorization sees as indefinite).

The CSV has one row per stored prior: run, mode, event, frame, n, and for each scaling
lambda_max, lambda_obs_min, kappa, neg. --plot: κ and −neg of the block-scaled priors against the
frame, one line per run (log axes; `neg` ≥ 0 drawn at 1e-17). Independent of the C++ implementation of the scalings
(core/linalg/preconditioner.cpp): numpy only.
"""
import argparse
import os
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import atomic_save  # noqa: E402

GAUGE_DIM = {"vio": 4, "vo": 6}
# Row layout: run, mode, event, frame, n, then (λ_max, λ_obs_min, κ, neg) per scaling.
BLOCK_KAPPA = 5 + 4 * 2 + 2
BLOCK_NEG = BLOCK_KAPPA + 1


def jacobi(H):
    d = np.diag(H).copy()
    s = np.ones_like(d)
    ok = np.isfinite(d) & (d > 0)
    s[ok] = np.ldexp(1.0, -np.rint(0.5 * np.log2(d[ok])).astype(int))
    return H * np.outer(s, s)


def block(H):
    n = H.shape[0]
    P = np.zeros_like(H)
    for k in range(0, n, 3):
        B = H[k:k + 3, k:k + 3]
        try:
            L = np.linalg.cholesky(B)
            P[k:k + 3, k:k + 3] = np.linalg.inv(L).T
        except np.linalg.LinAlgError:
            d = np.diag(B)
            P[k:k + 3, k:k + 3] = np.diag(np.where(d > 0, 1.0 / np.sqrt(np.abs(d) + (d <= 0)), 1.0))
    return P.T @ H @ P


def stats(H, g):
    ev = np.linalg.eigvalsh(0.5 * (H + H.T))
    lam_max = ev[-1]
    lam_obs = ev[g] if len(ev) > g else float("nan")
    return lam_max, lam_obs, lam_max / lam_obs if lam_obs > 0 else float("inf"), ev[0] / lam_max


def mode_of(f):
    mode = f.attrs.get("mode", None)
    if isinstance(mode, bytes):
        mode = mode.decode()
    if mode in GAUGE_DIM:
        return mode
    dataset = f.attrs["dataset"]
    dataset = dataset.decode() if isinstance(dataset, bytes) else dataset
    return "vo" if "kitti" in dataset else "vio"


def rows_of(path):
    out = []
    with h5py.File(path, "r") as f:
        mode = mode_of(f)
        g = GAUGE_DIM[mode]
        frame_index = np.asarray(f["marg/frame_index"])
        priors = f["marg/priors"]
        for key in sorted(priors.keys(), key=int):
            H = np.asarray(priors[key]["H_m"], dtype=float)
            row = [os.path.basename(path), mode, int(key), int(frame_index[int(key)]), H.shape[0]]
            for M in (H, jacobi(H), block(H)):
                row += list(stats(M, g))
            out.append(row)
    return out


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for run in dict.fromkeys(r[0] for r in rows):
        mine = [r for r in rows if r[0] == run]
        frame = [r[3] for r in mine]
        top.plot(frame, [r[BLOCK_KAPPA] for r in mine], label=run)
        bottom.plot(frame, [max(-r[BLOCK_NEG], 1e-17) for r in mine], label=run)
    top.set_yscale("log")
    bottom.set_yscale("log")
    top.set_ylabel("κ of the 3×3-block-scaled prior")
    bottom.set_ylabel("−λ_min / λ_max (block-scaled)")
    bottom.axhline(np.finfo(np.float32).eps, color="0.5", ls=":", lw=1)
    bottom.set_xlabel("frame")
    top.legend(fontsize=8)
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    atomic_save.savefig(fig, path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="+")
    parser.add_argument("--out", required=True)
    parser.add_argument("--plot")
    args = parser.parse_args()
    header = ["run", "mode", "event", "frame", "n"]
    for s in ("unscaled", "jacobi", "block"):
        header += [s + "_lambda_max", s + "_lambda_obs_min", s + "_kappa", s + "_neg"]
    lines = [",".join(header)]
    rows = [row for path in args.runs for row in rows_of(path)]
    if args.plot:
        plot(rows, args.plot)
    for row in rows:
        lines.append(",".join(v if isinstance(v, str) else ("%d" % v if isinstance(v, int)
                                                             else "%.6g" % v) for v in row))
    atomic_save.write_text(args.out, "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
