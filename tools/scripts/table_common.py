"""What the table scripts (nfr_topology_table.py, nfr_length_table.py, stop_rule_table.py: the
paired comparisons that `marglab tables` does not make; each script's header says why) share:
the seed statistics of a published cell, the ATE alignment and the atomic output files.

Seed statistics: the convention of core/experiment/table_run_stats.cpp and table_render.cpp
(sampleStdOf, spreadText, failedText), so a "mean ± std" reads the same in every published table
— the mean and the sample standard deviation s = sqrt(Σ (x_i − x̄)² / (n − 1)) of the values; with
fewer than two values there is no spread and the cell shows the mean alone. "x k/n": k of n runs
failed.

Alignment: the project's own ATE (core/diagnostics/ate.h, computeAte), not the independent
checker's (check_results.py must stay independent of what it checks). Pairs are the rows where
both p_est and p_gt are finite; R ∈ SO(3), t minimize Σ‖d_i − (R s_i + t)‖² for s = p_est, d = p_gt
(Umeyama without scale): μ_s, μ_d the means, Σ = (1/N) Σ (d_i − μ_d)(s_i − μ_s)ᵀ = U D Vᵀ,
R = U diag(1, 1, sign(det U det V)) Vᵀ (the reflection fix), t = μ_d − R μ_s;
ATE RMSE = sqrt(1/N Σ ‖d_i − (R s_i + t)‖²).

Output files: written to a temporary sibling and renamed (atomic_save.py), so a failure leaves the
previous table in place.
"""
import csv
import io
import math
import os
import statistics
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import atomic_save  # noqa: E402


def finite(values):
    return [v for v in values if np.isfinite(v)]


def mean(values):
    """Mean of the finite values; NaN when there are none."""
    v = finite(values)
    return statistics.fmean(v) if v else float("nan")


def sample_std(values):
    """Sample standard deviation (n − 1); NaN for fewer than two values (sampleStdOf of
    table_run_stats.cpp)."""
    return statistics.stdev(values) if len(values) >= 2 else float("nan")


def seed_cell(values, n_failed, n_runs, digits):
    """"mean ± std (n)" of the ok runs' values, then " x k/n" when k of the n runs failed; "–"
    without values (and no failure)."""
    cell = ""
    if values:
        spread = sample_std(values)
        cell = f"{statistics.fmean(values):.{digits}f}"
        if math.isfinite(spread):
            cell += f" ± {spread:.{digits}f}"
        cell += f" ({len(values)})"
    if n_failed:
        cell = (cell + " " if cell else "") + f"x {n_failed}/{n_runs}"
    return cell or "–"


def align_rigid(src, dst):
    """(R, t) with dst ≈ R src + t (see the header); src, dst are N×3 with N ≥ 1."""
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    sigma = (dst - mu_d).T @ (src - mu_s) / len(src)
    u, _, vt = np.linalg.svd(sigma)
    s = np.array([1.0, 1.0, -1.0 if np.linalg.det(u) * np.linalg.det(vt) < 0.0 else 1.0])
    rot = (u * s) @ vt
    return rot, mu_d - rot @ mu_s


def ate_rmse(p_est, p_gt):
    """ATE RMSE over the rows where both are finite, after align_rigid; NaN without such rows."""
    ok = np.all(np.isfinite(p_est), axis=1) & np.all(np.isfinite(p_gt), axis=1)
    if not ok.any():
        return float("nan")
    src, dst = p_est[ok], p_gt[ok]
    rot, trans = align_rigid(src, dst)
    err = np.linalg.norm(dst - (src @ rot.T + trans), axis=1)
    return float(np.sqrt(np.mean(err ** 2)))


def write_text(path, text):
    """Writes text to path atomically."""
    atomic_save.write_text(path, text)


def write_csv(path, rows):
    """Writes the rows (the first one the header) to path atomically, as csv.writer would."""
    buffer = io.StringIO(newline="")
    csv.writer(buffer).writerows(rows)
    atomic_save.write_text(path, buffer.getvalue())
