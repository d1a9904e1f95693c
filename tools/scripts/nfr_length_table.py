#!/usr/bin/env python3
"""ATE against run length for discard and nfr on the same (sequence, seed) pairs
(experiments/nfr_length.toml, issue #19 section 3), and for nfr with rigid deflation where the
sweep has it (override nfr_deflated, experiments/nfr_length_deflation.toml, issue #31 section 2).

Usage: nfr_length_table.py SWEEP_DIR [MORE_SWEEP_DIRS...]   (the runs of all folders, e.g. one
per seed; writes SWEEP_DIR/tables/length.{md,csv} and SWEEP_DIR/figures/length.{png,pdf}, and
with nfr_deflated runs SWEEP_DIR/figures/length_nfr_deflated.{png,pdf})

A run is causal: frames 1..N of a whole run are bit for bit the N-frame run (checked by
test/cli/nfr_length_agrees.py). So the ATE of an N-frame run is the ATE of the first N frames of
the whole run, aligned on their own: Umeyama without scale, with the reflection fix, as
core/diagnostics/ate.h (table_common.ate_rmse), over the frames whose p_est and p_gt are both
finite. Per prefix length: the (sequence, seed) pairs where nfr's ATE is below discard's, and
the geometric mean of ATE(nfr) / ATE(discard). Per 400-frame segment, each aligned on its own, the
same comparison of local accuracy: does nfr lose locally late in a run, or only in accumulated
drift? And the whole run's attitude error against the ground truth's orientation, split into tilt
(observable through gravity) and yaw (unobservable): which one does nfr lose in? Needs numpy,
scipy, h5py, pandas (marglab_results.py) and matplotlib, and the shipped
datasets/*/gt_tum.txt.gz. With nfr_deflated runs: the same comparisons of nfr_deflated against
discard and against nfr, a summary of the three by run length, and the median information
ratio εᵀΛ_sε / εᵀΛ_tε of nfr and nfr_deflated along the gauge directions (/sparsify), which shows
whether the deflation did what it is for (1 along x … yaw).

Why not `marglab tables`: a cell there reduces one number per run over the seeds of one dataset ×
column (core/experiment/table_specs.h); this script re-aligns prefixes and segments of each run's
trajectory, compares two strategies pair by pair on the same (sequence, seed), reads the shipped
ground-truth orientations and draws figures.
"""
import gzip
import math
import os
import statistics
import sys

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import atomic_save  # noqa: E402
import marglab_results as mr  # noqa: E402
from table_common import align_rigid, ate_rmse, write_csv, write_text  # noqa: E402

DATASETS = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(
    os.path.abspath(__file__)))), "datasets")

PREFIXES = [200, 400, 800, 1200, 1600]  # frames; "whole" is added per run
SEGMENT = 400                           # frames per segment of the local comparison
CURVE_STEP = 100                        # frames between the prefixes of the figure
GT_MAX_DT_NS = 5_000_000                # nearest GT orientation within 5 ms (EuRoC GT: 200 Hz)


def prefix_ate(run, n):
    """ATE of the first n frames of `run` (a marglab_results.Run), aligned on their own."""
    return ate_rmse(run.positions("p_est")[:n], run.positions("p_gt")[:n])


def segment_ates(run):
    """ATE of each whole SEGMENT-frame segment, each aligned on its own."""
    p_est, p_gt = run.positions("p_est"), run.positions("p_gt")
    return [ate_rmse(p_est[k:k + SEGMENT], p_gt[k:k + SEGMENT])
            for k in range(0, len(p_est) - SEGMENT + 1, SEGMENT)]


def attitude_rms(p_est, q_est, p_gt, q_gt):
    """(tilt, yaw) RMS [deg] of the attitude error after the run's own position alignment
    (R, t) = align_rigid(p_est, p_gt): E = (R R_est) R_gtᵀ, a world-frame rotation per frame; tilt
    is the angle E moves gravity's axis e_z by (observable through the accelerometer), yaw E's
    rotation about e_z (unobservable in VIO). q_* are xyzw rows; rows with a non-finite value are
    skipped."""
    ok = np.all(np.isfinite(np.hstack([p_est, q_est, p_gt, q_gt])), axis=1)
    R, _ = align_rigid(p_est[ok], p_gt[ok])
    E = ((Rotation.from_matrix(R) * Rotation.from_quat(q_est[ok])) *
         Rotation.from_quat(q_gt[ok]).inv()).as_matrix()
    tilt = np.degrees(np.arctan2(np.hypot(E[:, 0, 2], E[:, 1, 2]), E[:, 2, 2]))  # ∠(E e_z, e_z)
    yaw = np.degrees(np.arctan2(E[:, 1, 0] - E[:, 0, 1], E[:, 0, 0] + E[:, 1, 1]))
    return float(np.sqrt(np.mean(tilt ** 2))), float(np.sqrt(np.mean(yaw ** 2)))


def gt_orientations(run):
    """GT orientation (xyzw) at each frame of `run` from the shipped datasets/<dataset>/<sequence>/
    gt_tum.txt.gz: the nearest sample within GT_MAX_DT_NS, else NaN."""
    path = os.path.join(DATASETS, run.attrs["dataset"], run.attrs["sequence"], "gt_tum.txt.gz")
    with gzip.open(path, "rt") as f:
        gt = np.loadtxt(f, comments="#")
    t_gt = np.round(gt[:, 0] * 1e9).astype(np.int64)
    t = np.asarray(run.frames["t_ns"], dtype=np.int64)
    k = np.clip(np.searchsorted(t_gt, t), 1, len(t_gt) - 1)
    k = np.where(np.abs(t_gt[k - 1] - t) < np.abs(t_gt[k] - t), k - 1, k)
    q = gt[k, 4:8].copy()
    q[np.abs(t_gt[k] - t) > GT_MAX_DT_NS] = np.nan
    return q


def information_ratios(run):
    """Median over the events of εᵀΛ_sε / εᵀΛ_tε per gauge direction, and the mean KLD of the
    recovered events ({} without /sparsify)."""
    sp = run.sparsify
    if len(sp) == 0 or "info_dense_x" not in sp:
        return {}
    out = {d: float(np.median(np.asarray(sp["info_sparse_" + d], dtype=float) /
                              np.asarray(sp["info_dense_" + d], dtype=float)))
           for d in mr.DEM_DIRECTIONS}
    kld = np.asarray(sp["kld"], dtype=float)[np.asarray(sp["recovered"], dtype=bool)]
    out["kld"] = float(np.mean(kld)) if kld.size else float("nan")
    return out


def load(sweep):
    """{(override, dataset, seed): {"n": frames, "curve": {L: ate} every CURVE_STEP frames,
    "prefix": {L: ate} at PREFIXES and "whole", "segments": [ate], "tilt": deg, "yaw": deg,
    "info": {direction: ratio}}} of the runs that completed; a failed run is left out (with its
    pair)."""
    runs = {}
    for row in mr.read_index_rows(sweep):
        path = row["path"]
        if row["status"] != "ok" or not os.path.exists(path):
            continue
        run = mr.read_run(path)
        n = len(run.frames["t_ns"])
        curve = {L: prefix_ate(run, L) for L in range(CURVE_STEP, n + 1, CURVE_STEP)}
        prefix = {L: curve[L] for L in PREFIXES if L <= n}  # PREFIXES are multiples of the step
        prefix["whole"] = prefix_ate(run, n)
        if not math.isclose(prefix["whole"], float(run.summary["ate_rmse"]), rel_tol=1e-9):
            raise SystemExit("%s: whole-run ATE %.17g here, %.17g in /summary"
                             % (path, prefix["whole"], float(run.summary["ate_rmse"])))
        q_est = np.column_stack([np.asarray(run.frames["q_est_" + a]) for a in "xyzw"])
        tilt, yaw = attitude_rms(run.positions("p_est"), q_est, run.positions("p_gt"),
                                 gt_orientations(run))
        runs[(row["override"], row["dataset"].split("/")[-1], int(row["seed"]))] = {
            "n": n, "curve": curve, "prefix": prefix, "segments": segment_ates(run), "tilt": tilt,
            "yaw": yaw, "info": information_ratios(run)}
    return runs


def pairs(runs, a="discard", b="nfr"):
    """[(dataset, seed, run of a, run of b)] for the pairs where both completed."""
    out = []
    for (o, d, s), r in sorted(runs.items()):
        if o == a and (b, d, s) in runs:
            out.append((d, s, r, runs[(b, d, s)]))
    return out


def compare(values):
    """(b better, pairs, geometric mean of b / a) over [(a, b)] values (ATEs, attitude errors)."""
    v = [(a, b) for a, b in values if np.isfinite(a) and np.isfinite(b) and a > 0]
    if not v:
        return 0, 0, float("nan")
    return (sum(b < a for a, b in v), len(v),
            math.exp(statistics.fmean(math.log(b / a) for a, b in v)))


def length_lines(ps, a="discard", b="nfr"):
    lines = [f"| run length [frames] | {b} < {a} | ATE({b}) / ATE({a}), geo. mean |",
             "|---|---:|---:|"]
    for L in PREFIXES + ["whole"]:
        better, n, geo = compare([(d["prefix"][L], f["prefix"][L]) for _, _, d, f in ps
                                  if L in d["prefix"] and L in f["prefix"]])
        lines.append(f"| {L} | {better} / {n} | {geo:.3f} |")
    return lines


def segment_lines(ps, a="discard", b="nfr"):
    lines = [f"| segment [frames] | {b} < {a} | ATE({b}) / ATE({a}), geo. mean |",
             "|---|---:|---:|"]
    k = 0
    while True:
        vals = [(d["segments"][k], f["segments"][k]) for _, _, d, f in ps
                if k < len(d["segments"]) and k < len(f["segments"])]
        if len(vals) < 3:
            return lines
        better, n, geo = compare(vals)
        lines.append(f"| {k * SEGMENT}–{(k + 1) * SEGMENT} | {better} / {n} | {geo:.3f} |")
        k += 1


def attitude_lines(ps, a="discard", b="nfr"):
    lines = [f"| attitude error, whole runs (RMS) | {a}, mean [deg] | {b}, mean [deg] | "
             f"{b} < {a} | {b} / {a}, geo. mean |", "|---|---:|---:|---:|---:|"]
    for key, what in (("tilt", "tilt (gravity axis; observable)"),
                      ("yaw", "yaw (about gravity; unobservable)")):
        better, n, geo = compare([(d[key], f[key]) for _, _, d, f in ps])
        lines.append(f"| {what} | {statistics.fmean(d[key] for _, _, d, _ in ps):.3f} | "
                     f"{statistics.fmean(f[key] for _, _, _, f in ps):.3f} | {better} / {n} | "
                     f"{geo:.3f} |")
    return lines


def pair_lines(ps):
    cols = PREFIXES + ["whole"]
    lines = ["| sequence | seed | frames | " + " | ".join(map(str, cols)) + " | tilt | yaw |",
             "|---|---:|---:|" + "---:|" * (len(cols) + 2)]
    for d, s, dr, fr in ps:
        cells = [f"{fr['prefix'][L] / dr['prefix'][L]:.2f}" if L in dr["prefix"] else "–"
                 for L in cols]
        cells += [f"{fr[k] / dr[k]:.2f}" for k in ("tilt", "yaw")]
        lines.append(f"| {d} | {s} | {dr['n']} | " + " | ".join(cells) + " |")
    return lines


def summary_lines(runs, comparisons):
    """Per run length and for tilt / yaw: better-in and geometric-mean ratio of each (a, b)."""
    head = " | ".join(f"{b} / {a}" for a, b in comparisons)
    lines = [f"| run length [frames] | {head} |", "|---|" + "---:|" * len(comparisons)]
    for L in PREFIXES + ["whole", "tilt", "yaw"]:
        cells = []
        for a, b in comparisons:
            ps = pairs(runs, a, b)
            if L in ("tilt", "yaw"):
                better, n, geo = compare([(x[L], y[L]) for _, _, x, y in ps])
            else:
                better, n, geo = compare([(x["prefix"][L], y["prefix"][L]) for _, _, x, y in ps
                                          if L in x["prefix"] and L in y["prefix"]])
            cells.append(f"{geo:.3f} ({better} / {n})")
        label = f"{L} (attitude RMS, whole runs)" if L in ("tilt", "yaw") else str(L)
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return lines


def information_lines(runs, overrides):
    """Mean over the runs of each run's median information ratio, per direction."""
    lines = ["| strategy | runs | " + " | ".join(mr.DEM_DIRECTIONS) + " | KLD per event [nats] |",
             "|---|---:|" + "---:|" * (len(mr.DEM_DIRECTIONS) + 1)]
    for o in overrides:
        sel = [r["info"] for k, r in sorted(runs.items()) if k[0] == o and r["info"]]
        if sel:
            lines.append(f"| {o} | {len(sel)} | " + " | ".join(
                f"{statistics.fmean(i[d] for i in sel):.3f}" for d in mr.DEM_DIRECTIONS + ["kld"])
                + " |")
    return lines


def write_figure(out_dir, ps, b="nfr", name="length"):
    """ATE(b) / ATE(discard) against run length: one line per pair, coloured by sequence, and
    the geometric mean over the pairs that reach each length, up to the lengths at least half of
    the pairs reach (figures/<name>.{png,pdf})."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    colours = {d: plt.cm.tab10(k % 10) for k, d in enumerate(sorted({p[0] for p in ps}))}
    by_length = {}
    for d, s, dr, fr in ps:
        lengths = sorted(set(dr["curve"]) & set(fr["curve"]))
        ratios = [fr["curve"][L] / dr["curve"][L] for L in lengths]
        ax.plot(lengths, ratios, color=colours[d], lw=0.7, alpha=0.6,
                label=d if s == min(p[1] for p in ps if p[0] == d) else None)
        for L, r in zip(lengths, ratios):
            by_length.setdefault(L, []).append(math.log(r))
    lengths = sorted(L for L, v in by_length.items() if 2 * len(v) >= len(ps))
    ax.plot(lengths, [math.exp(statistics.fmean(by_length[L])) for L in lengths], color="black",
            lw=2.2, label="geometric mean (lengths half the pairs reach)")
    ax.axhline(1.0, color="grey", lw=0.8, ls="--")
    ax.set_yscale("log")
    ax.set_xlabel("run length [frames]")
    ax.set_ylabel(f"ATE({b}) / ATE(discard)")
    ax.set_title(f"{b} against discard on the same runs, by run length")
    ax.legend(fontsize=7, ncol=3, loc="upper left")
    fig.tight_layout()
    os.makedirs(out_dir, exist_ok=True)
    for ext in ("png", "pdf"):  # no creation date: the same runs give the same file
        atomic_save.savefig(fig, os.path.join(out_dir, name + "." + ext), dpi=150,
                            metadata={"CreationDate": None} if ext == "pdf" else None)
    plt.close(fig)


def csv_rows(runs):
    rows = [["strategy", "dataset", "seed", "frames", "kind", "length_or_segment", "value"]]
    for (o, d, s), r in sorted(runs.items()):
        rows += [[o, d, s, r["n"], "prefix_ate_m", L, repr(ate)] for L, ate in r["prefix"].items()]
        rows += [[o, d, s, r["n"], "segment_ate_m", k * SEGMENT, repr(ate)]
                 for k, ate in enumerate(r["segments"])]
        rows += [[o, d, s, r["n"], key + "_rms_deg", "whole", repr(r[key])]
                 for key in ("tilt", "yaw")]
    return rows


def comparison_lines(ps, a, b):
    lines = length_lines(ps, a, b)
    lines += ["", f"Local accuracy: the ATE of each {SEGMENT}-frame segment, aligned on its own "
              "(pairs with that segment).", ""]
    lines += segment_lines(ps, a, b)
    lines += ["", "Attitude error of the whole runs against the shipped ground truth's orientation, "
              "after each run's own position alignment.", ""]
    lines += attitude_lines(ps, a, b)
    lines += ["", f"{b} / {a} per pair: ATE by run length, then the whole run's tilt and yaw "
              f"RMS (below 1: {b} better).", ""]
    lines += pair_lines(ps)
    return lines


def main():
    if len(sys.argv) < 2:
        print(__doc__.strip().splitlines()[4], file=sys.stderr)
        return 2
    sweep = sys.argv[1]
    runs = {}
    for folder in sys.argv[1:]:
        runs.update(load(folder))
    ps = pairs(runs)
    names = ", ".join(f"`{os.path.basename(os.path.normpath(f))}`" for f in sys.argv[1:])
    lines = ["# nfr against discard by run length (issue #19, section 3)", "",
             f"Sweep {names}: {len(ps)} (sequence, seed) "
             "pairs where both runs completed. ATE RMSE of the first N frames of each run, "
             "aligned on their own (what an N-frame run reports).", ""]
    deflated = any(k[0] == "nfr_deflated" for k in runs)
    if deflated:
        comparisons = [("discard", "nfr"), ("discard", "nfr_deflated"), ("nfr", "nfr_deflated")]
        lines += ["## Summary: nfr with and without rigid deflation (issue #31, section 2)", "",
                  "Geometric mean of the ratio (pairs where the second is better / pairs).", ""]
        lines += summary_lines(runs, comparisons)
        lines += ["", "Information of the recovered factors relative to the dense prior along the "
                  "gauge directions (/sparsify info_sparse / info_dense: median over a run's "
                  "events, mean over the runs), and the KLD to the dense prior (/sparsify kld: "
                  "mean over a run's events, mean over the runs).", ""]
        lines += information_lines(runs, ["nfr", "nfr_deflated"])
        lines += ["", "## nfr against discard", ""]
    lines += comparison_lines(ps, "discard", "nfr")
    if deflated:
        for a in ("discard", "nfr"):
            lines += ["", f"## nfr_deflated against {a}", ""]
            lines += comparison_lines(pairs(runs, a, "nfr_deflated"), a, "nfr_deflated")
    out_dir = os.path.join(sweep, "tables")
    os.makedirs(out_dir, exist_ok=True)
    write_csv(os.path.join(out_dir, "length.csv"), csv_rows(runs))
    write_text(os.path.join(out_dir, "length.md"), "\n".join(lines) + "\n")
    write_figure(os.path.join(sweep, "figures"), ps)
    if deflated:
        write_figure(os.path.join(sweep, "figures"), pairs(runs, "discard", "nfr_deflated"),
                     "nfr_deflated", "length_nfr_deflated")
    print(os.path.join(out_dir, "length.md"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
