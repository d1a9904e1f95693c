#!/usr/bin/env python3
"""Figures of Demmel et al. (ICCV 2021) from marglab sweep results (HDF5 files listed in index.csv).

Usage: plot_paper.py --out DIR [--vio-dataset euroc/MH_01_easy] [--vo-dataset kitti/10]
                     [--figures fig1,fig4,fig4_yaw,fig5,fig6,fig7,sparsify,ba_convergence,
                                ba_profile] SWEEP_DIR [SWEEP_DIR ...]

Writes PNG and PDF into DIR (slug = dataset with '/' -> '-'):
  fig1_<slug>            Fig. 1 analog on the VIO dataset: top-down trajectories of the four headline
                         variants (sqrt-64, sqrt-32, SC-64, SC-32) after SE(3) alignment against the
                         reference, and sigma_min of the gauge-free prior over time (symlog y axis,
                         linear within +-1e-8)
  fig4_dEm_<slug>        Fig. 4 analog: Delta E_m (eq. 27) along x, y, z, roll, pitch, yaw and a random
                         unit direction over time, one panel per variant, VIO dataset
  fig4_yaw_<slug>        Fig. 4's finding over seeds: rho = |Delta E_m(yaw)| / min(|Delta E_m(roll)|,
                         |Delta E_m(pitch)|) at every marginalization of every headline run of the VIO
                         dataset (all seeds), one panel per variant; rho near 1 = yaw as observable
                         as roll and pitch (the paper: VIO-32 from around frame 2000). The per-run
                         onset frames go to fig4_yaw_<slug>.csv (columns in YAW_CSV_COLUMNS)
  fig5_dEm_<slug>        Fig. 5 analog: the same on the VO dataset
  fig6_sigma_min_<slug>  Fig. 6 analog: sigma_min over time on the VO dataset
  fig7_trajectory_<slug> Fig. 7 analog: top-down trajectories on the VO dataset
and, from runs whose results attribute marg_strategy is nfr (Hsiung et al., IROS 2018), figure
`sparsify`:
  sparsify_fig6a         Fig. 6a analog: optimization and marginalization time of every keyframe
                         (/frames t_opt_s, t_marg_s of the frames with is_keyframe) over the
                         keyframe index, MH_02_easy left, V1_02_medium right (those present)
  sparsify_fig6b         Fig. 6b analog: box plots per sequence of the optimization time per frame
                         and the marginalization time per keyframe marginalization (frames with a
                         /sparsify row), and of the steps of those events: t_schur_s, and
                         t_recovery_s, t_insert_s of the events whose factors were recovered
  sparsify_kld           D_KL (eq. 10, /sparsify kld) of every recovered event over time, every nfr
                         run (lowest seed, most frames per sequence)
and, from `marglab ba` runs (index column kind = "ba"; ba_figures.py), figures `ba_convergence`
(cost − best against time per group and problem) and `ba_profile` (rootba's performance profile
per group);
and, from VIO runs of the IMU noise profiles (results attribute config_toml, [imu]
noise_profile; issue #19), figure `noise_sigma`:
  noise_sigma            sigma_max and sigma_min (/marg) of the prior at the first 20
                         marginalizations, one thin line per sequence and profile (kalibr, basalt),
                         the median over sequences bold; the values plotted also go to
                         noise_sigma.csv (dataset, profile, variant, event, sigma_max, sigma_min)
The family label (VIO / VO) comes from each results file's `mode` attribute, so the figures say what
the estimator actually ran. A run that failed is drawn up to its failure and marked with an x.
Needs matplotlib, h5py and numpy (Debian: python3-matplotlib python3-h5py python3-numpy).
"""
import argparse
import os
import sys

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import atomic_save  # noqa: E402
import ba_figures  # noqa: E402
import marglab_results as mr  # noqa: E402  (the results schema on the Python side)
from marglab_results import HEADLINE, slug  # noqa: E402

STYLE = {
    "ns-qr-sqrt-f64": dict(color="tab:blue", ls="-", lw=1.6),
    "ns-qr-sqrt-f32": dict(color="tab:green", ls="--", lw=1.4),
    "sc-sc-sq-f64": dict(color="tab:orange", ls="-", lw=1.2),
    "sc-sc-sq-f32": dict(color="tab:red", ls="-", lw=1.2),
}
DIRECTIONS = ["x", "y", "z", "roll", "pitch", "yaw", "random"]
DIRECTION_COLORS = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
                    "0.4"]
LINTHRESH = 1e-8


def label(variant, mode):
    """The paper's name of a variant, with matplotlib's square root."""
    name = mr.label(variant, mode)
    if name.startswith("\u221a"):
        family, bits = name[1:].split("-")
        return r"$\sqrt{\mathrm{%s}}$-%s" % (family, bits)
    return name


class Run:
    """One results file (marglab_results.Run) with the index row it came from."""

    def __init__(self, path, row):
        run = mr.read_run(path)
        self.path = path
        self.row = row
        self.variant = run.variant
        self.mode = run.mode
        self.status = run.status
        self.failure_frame = run.failure_frame
        self.ate = float(run.summary["ate_rmse"])
        self.t_ns = np.asarray(run.frames["t_ns"])
        self.p_gt = run.positions("p_gt")
        self.p_est_aligned = run.aligned()
        self.marg_t = np.asarray(run.marg["t_s"])
        self.marg_frame = np.asarray(run.marg["frame_index"])
        self.sigma_min = np.asarray(run.marg["sigma_min"])
        self.dEm = np.column_stack([np.asarray(run.marg["dEm_" + d]) for d in mr.DEM_DIRECTIONS]) \
            if len(self.marg_t) else np.zeros((0, 7))
        self.fail_t = run.failure_time()

    def failure_time(self):
        return self.fail_t

    def aligned(self):
        return self.p_est_aligned

    def name(self):
        return label(self.variant, self.mode)


def read_rows(dirs):
    """The index rows of the sweeps, keyed by the datasets' recorded kind and sequence (a user's
    folder is indexed by its path), as `marglab tables` keys them."""
    rows = []
    for d in dirs:
        for row in mr.read_index_rows(d):
            row["_path"] = row["path"]
            rows.append(row)
    for warning in mr.key_datasets(rows):
        print("warning: " + warning, file=sys.stderr)
    return rows


def select(rows, dataset):
    """The headline runs of a dataset: no override (else the first), lowest seed, most frames."""
    candidates = [r for r in rows if r["dataset"] == dataset and r["variant"] in HEADLINE
                  and os.path.isfile(r["_path"])]
    if not candidates:
        return []
    overrides = sorted({r["override"] for r in candidates})
    chosen_override = "" if "" in overrides else overrides[0]
    best = {}
    for r in candidates:
        if r["override"] != chosen_override:
            continue
        frames = int(r["frames"] or 0) or 10 ** 12
        key = r["variant"]
        rank = (-int(r["seed"]), frames)
        if key not in best or rank > best[key][0]:
            best[key] = (rank, r)
    runs = []
    for v in HEADLINE:
        if v in best:
            try:
                runs.append(Run(best[v][1]["_path"], best[v][1]))
            except (OSError, KeyError, mr.SchemaError) as e:
                print("warning: cannot read %s: %s" % (best[v][1]["_path"], e), file=sys.stderr)
    return runs


def nfr_runs(rows):
    """{dataset: h5 path} of the nfr runs, one per dataset: lowest seed, most frames."""
    best = {}
    for r in rows:
        if r.get("status") != "ok" or not os.path.isfile(r["_path"]):
            continue
        try:
            if mr.run_summary(r["_path"])["marg_strategy"] != "nfr":
                continue
        except (OSError, KeyError) as e:
            print("warning: cannot read %s: %s" % (r["_path"], e), file=sys.stderr)
            continue
        rank = (-int(r["seed"]), int(r["frames"] or 0) or 10 ** 12)
        if r["dataset"] not in best or rank > best[r["dataset"]][0]:
            best[r["dataset"]] = (rank, r["_path"])
    return {d: path for d, (_, path) in sorted(best.items())}


def read_timing(path):
    run = mr.read_run(path)
    fr, sp = run.frames, run.sparsify
    col = lambda table, name: np.asarray(table[name])
    keyframe = col(fr, "is_keyframe").astype(bool)
    event_frames = col(sp, "frame_index").astype(np.int64)
    recovered = col(sp, "recovered").astype(bool)
    return dict(
        t_opt=col(fr, "t_opt_s"), t_marg=col(fr, "t_marg_s"), keyframe=keyframe,
        marg_kf=col(fr, "t_marg_s")[event_frames],
        schur=col(sp, "t_schur_s"), recovery=col(sp, "t_recovery_s")[recovered],
        insert=col(sp, "t_insert_s")[recovered],
        kld_t=(col(sp, "t_ns").astype(np.int64) - run.t0_ns)[recovered] * 1e-9,
        kld=col(sp, "kld")[recovered])


def plot_sparsify(runs, out, written):
    """Hsiung et al. Fig. 6a / 6b analogs on MH_02_easy and V1_02_medium, and the KLD series."""
    timing = {d: read_timing(p) for d, p in runs.items()}
    fig6 = [d for d in ("euroc/MH_02_easy", "euroc/V1_02_medium") if d in timing]
    if not fig6:
        print("skipped sparsify_fig6a, sparsify_fig6b: no nfr run of MH_02_easy or V1_02_medium")
    else:
        fig, axes = plt.subplots(1, len(fig6), figsize=(6 * len(fig6), 3.5), squeeze=False)
        for ax, d in zip(axes[0], fig6):
            t = timing[d]
            ax.plot(t["t_opt"][t["keyframe"]], color="tab:blue", lw=0.8, label="optimization")
            ax.plot(t["t_marg"][t["keyframe"]], color="tab:red", lw=0.8, label="marginalization")
            ax.set_xlabel("keyframe")
            ax.set_ylabel("time [s]")
            ax.set_title("%s (nfr)" % d)
            ax.legend(fontsize=8)
        fig.tight_layout()
        save(fig, out, "sparsify_fig6a", written)

        fig, axes = plt.subplots(1, 2 * len(fig6), figsize=(5.5 * len(fig6), 3.5), squeeze=False)
        for i, d in enumerate(fig6):
            t = timing[d]
            left, right = axes[0][2 * i], axes[0][2 * i + 1]
            left.boxplot([t["t_opt"], t["marg_kf"]], showfliers=False)
            left.set_xticks([1, 2], ["opt\nper frame", "marg\nper keyframe"], fontsize=8)
            left.set_ylabel("time [s]")
            left.set_title(d, fontsize=9)
            right.boxplot([t["schur"], t["recovery"], t["insert"]], showfliers=False)
            right.set_xticks([1, 2, 3], ["Schur /\nflat QR", "recovery\n(eq. 16)", "insert"], fontsize=8)
            right.set_title("steps of marginalization", fontsize=9)
        fig.tight_layout()
        save(fig, out, "sparsify_fig6b", written)

    fig, ax = plt.subplots(figsize=(8, 4))
    for d, t in timing.items():
        ax.plot(t["kld_t"], t["kld"], lw=0.8, label=d)
    ax.set_yscale("log")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(r"$D_{KL}(\Lambda_t \Vert \Lambda_s)$ [nats]")
    ax.set_title("information lost by sparsification (nfr, recovered events)")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    save(fig, out, "sparsify_kld", written)


def pick_dataset(rows, wanted, family_prefixes):
    present = sorted({r["dataset"] for r in rows if r["variant"] in HEADLINE})
    if wanted in present:
        return wanted
    fallback = [d for d in present if d.startswith(family_prefixes)]
    if fallback:
        print("note: %s has no runs here; using %s" % (wanted, fallback[0]))
        return fallback[0]
    return None


def plane_axes(p_gt):
    """The two axes with the largest extent of the reference: top-down for EuRoC (x, y) and
    KITTI (x, z)."""
    finite = p_gt[np.all(np.isfinite(p_gt), axis=1)]
    if len(finite) == 0:
        return 0, 1
    extent = finite.max(axis=0) - finite.min(axis=0)
    a, b = sorted(np.argsort(extent)[-2:])
    return int(a), int(b)


def plot_trajectories(ax, runs, title):
    ref = max(runs, key=lambda r: len(r.t_ns))
    a, b = plane_axes(ref.p_gt)
    gt = ref.p_gt[np.all(np.isfinite(ref.p_gt), axis=1)]
    ax.plot(gt[:, a], gt[:, b], color="k", lw=3.0, alpha=0.25, label="reference")
    for run in runs:
        p = run.aligned()
        ok = np.all(np.isfinite(p), axis=1)
        name = run.name()
        if run.status == "failed":
            name += " (failed, frame %d)" % run.failure_frame
        else:
            name += " (ATE %.3f m)" % run.ate
        ax.plot(p[ok, a], p[ok, b], label=name, **STYLE[run.variant])
        if run.status == "failed" and ok.any():
            last = p[ok][-1]
            ax.plot(last[a], last[b], "x", color=STYLE[run.variant]["color"], ms=10, mew=2)
    lo, hi = gt.min(axis=0), gt.max(axis=0)
    margin = 0.15 * max(hi[a] - lo[a], hi[b] - lo[b], 1e-3)
    ax.set_xlim(lo[a] - margin, hi[a] + margin)
    ax.set_ylim(lo[b] - margin, hi[b] + margin)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("xyz"[a] + " [m]")
    ax.set_ylabel("xyz"[b] + " [m]")
    ax.set_title(title)
    ax.legend(fontsize=8, loc="best")


def plot_sigma_min(ax, runs, title):
    for run in runs:
        ax.plot(run.marg_t, run.sigma_min, label=run.name(), **STYLE[run.variant])
        ft = run.failure_time()
        if ft is not None:
            ax.axvline(ft, color=STYLE[run.variant]["color"], ls=":", lw=1)
            if len(run.sigma_min):
                ax.plot(run.marg_t[-1], run.sigma_min[-1], "x",
                        color=STYLE[run.variant]["color"], ms=9, mew=2)
    ax.set_yscale("symlog", linthresh=LINTHRESH)
    ax.axhspan(-LINTHRESH, LINTHRESH, color="0.92", zorder=0)
    ax.axhline(0, color="0.5", lw=0.5)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(r"$\sigma_{\min}(H_m)$ (gauge-free prior)")
    ax.set_title(title)
    ax.legend(fontsize=8, loc="best")
    ax.grid(True, which="major", alpha=0.3)


def plot_dEm(fig, runs, title):
    axes = fig.subplots(2, 2, sharex=True, sharey=True).ravel()
    for ax, run in zip(axes, runs):
        t = run.marg_t
        for j, (d, c) in enumerate(zip(DIRECTIONS, DIRECTION_COLORS)):
            ax.plot(t, run.dEm[:, j], color=c, lw=1.0, label=d, ls=":" if d == "random" else "-")
        ft = run.failure_time()
        if ft is not None:
            ax.axvline(ft, color="k", ls=":", lw=1)
        ax.set_yscale("symlog", linthresh=LINTHRESH)
        ax.axhspan(-LINTHRESH, LINTHRESH, color="0.92", zorder=0)
        ax.set_title(run.name() + (" (failed)" if run.status == "failed" else ""))
        ax.grid(True, alpha=0.3)
    for ax in axes[len(runs):]:
        ax.set_visible(False)
    for ax in axes[2:]:
        ax.set_xlabel("time [s]")
    for ax in axes[::2]:
        ax.set_ylabel(r"$\Delta E_m$ (eq. 27)")
    axes[0].legend(fontsize=7, ncol=2, loc="best")
    fig.suptitle(title)


# Fig. 4's finding: yaw "as observable as roll and pitch" when rho = |dEm_yaw| / min(|dEm_roll|,
# |dEm_pitch|) comes within a decade of 1 (YAW_LEVEL); a gauge direction has rho ~ 1e-14 in f64.
# The running median of rho over YAW_WINDOW events (5 s at 20 Hz; a spike does not count) gives
# the rise — the first event where it reaches YAW_ONSET — and the settling — the first event from
# which it stays >= YAW_ONSET to the end of the run: on MH_01 VIO-32 sits near 1e-3 before and
# near 0.05 after. Events where roll and pitch are not observable yet (min ΔE_m < YAW_MIN_LEVEL:
# the first marginalization) have no rho.
YAW_LEVEL = 0.1
YAW_ONSET = 0.01
YAW_WINDOW = 101
YAW_MIN_LEVEL = 1.0
YAW_CSV_COLUMNS = ["dataset", "variant", "seed", "status", "failure_frame", "events",
                   "rise_frame", "settled_frame", "first_frame_rho_0.1", "rho_median_before_rise",
                   "rho_median_after_rise", "share_after_rise_rho_0.01", "rho_median_from_2000"]


def yaw_ratio(run):
    """(frame_index, rho) of a run's marginalization events."""
    dem = np.abs(run.dEm)
    level = np.minimum(dem[:, 3], dem[:, 4])
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(level >= YAW_MIN_LEVEL, dem[:, 5] / level, np.nan)
    return run.marg_frame, rho


def yaw_onset(rho):
    """(rise, settled): indices of the first event where the running median of rho (centred
    window) reaches YAW_ONSET and of the first from which it stays there; None where none."""
    if np.count_nonzero(np.isfinite(rho)) < YAW_WINDOW:
        return None, None
    windows = np.lib.stride_tricks.sliding_window_view(np.nan_to_num(rho, nan=0.0), YAW_WINDOW)
    above = np.median(windows, axis=1) >= YAW_ONSET
    if not above.any():
        return None, None
    rise = int(np.argmax(above))
    below = np.flatnonzero(~above)
    settled = 0 if len(below) == 0 else below[-1] + 1
    half = YAW_WINDOW // 2
    return rise + half, (settled + half if settled < len(above) else None)


def yaw_row(dataset, run, frames, rho):
    """One line of fig4_yaw_<slug>.csv (YAW_CSV_COLUMNS)."""
    touched = np.flatnonzero(rho >= YAW_LEVEL)
    rise, settled = yaw_onset(rho)
    frame = lambda i: None if i is None else int(frames[i])
    after = rho[rise:] if rise is not None else rho[:0]
    share = float(np.mean(after[np.isfinite(after)] >= YAW_ONSET)) if len(after) else float("nan")
    return [dataset, run.variant, int(run.row["seed"]), run.status, run.failure_frame, len(rho),
            frame(rise), frame(settled), frame(touched[0]) if len(touched) else None,
            median_or_nan(rho[:rise] if rise is not None else rho), median_or_nan(after), share,
            median_or_nan(rho[frames >= 2000])]


def seed_runs(rows, dataset):
    """Every readable headline run of the dataset (all seeds), no override (else the first)."""
    candidates = [r for r in rows if r["dataset"] == dataset and r["variant"] in HEADLINE
                  and os.path.isfile(r["_path"])]
    overrides = sorted({r["override"] for r in candidates})
    chosen = "" if "" in overrides or not overrides else overrides[0]
    runs = []
    for r in sorted(candidates, key=lambda r: (HEADLINE.index(r["variant"]), int(r["seed"]))):
        if r["override"] != chosen:
            continue
        try:
            runs.append(Run(r["_path"], r))
        except (OSError, KeyError, mr.SchemaError) as e:
            print("warning: cannot read %s: %s" % (r["_path"], e), file=sys.stderr)
    return runs


def median_or_nan(values):
    values = values[np.isfinite(values)]
    return float(np.median(values)) if len(values) else float("nan")


def plot_yaw(runs, dataset, out, written):
    """Fig. 4's yaw finding over seeds: the figure and the onset table."""
    variants = [v for v in HEADLINE if any(r.variant == v for r in runs)]
    fig, axes = plt.subplots(1, len(variants), figsize=(4.2 * len(variants), 3.8), sharey=True,
                             squeeze=False)
    lines = []
    for ax, v in zip(axes[0], variants):
        for run in (r for r in runs if r.variant == v):
            frames, rho = yaw_ratio(run)
            ax.plot(frames, rho, lw=0.6, label="seed %s%s" % (
                run.row["seed"], " (failed)" if run.status == "failed" else ""))
            lines.append(yaw_row(dataset, run, frames, rho))
        ax.axhline(1.0, color="k", lw=0.8)
        ax.axhline(YAW_LEVEL, color="k", ls="--", lw=0.8)
        ax.axhline(YAW_ONSET, color="k", ls=":", lw=0.8)
        ax.set_yscale("log")
        ax.set_title(runs[[r.variant for r in runs].index(v)].name())
        ax.set_xlabel("frame")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    axes[0][0].set_ylabel(r"$|\Delta E_m(\mathrm{yaw})|\,/\,\min(|\Delta E_m(\mathrm{roll})|,"
                          r"|\Delta E_m(\mathrm{pitch})|)$")
    fig.suptitle("%s: yaw against roll/pitch in the prior (dashed: %g, within a decade of roll/"
                 "pitch; dotted: %g, the onset level)" % (dataset, YAW_LEVEL, YAW_ONSET))
    fig.tight_layout()
    name = "fig4_yaw_" + slug(dataset)
    save(fig, out, name, written)
    fmt = lambda x: "" if x is None else ("%.6g" % x if isinstance(x, float) else str(x))
    text = ",".join(YAW_CSV_COLUMNS) + "\n" + "".join(
        ",".join(fmt(x) for x in line) + "\n" for line in lines)
    path = os.path.join(out, name + ".csv")
    atomic_save.write_text(path, text)
    written.append(path)


PROFILE_COLORS = {"kalibr": "tab:blue", "basalt": "tab:orange"}
NOISE_EVENTS = 20


def noise_profile(config_toml):
    """[imu] noise_profile of a results file's config ("kalibr" before the key existed)."""
    section = ""
    for line in config_toml.splitlines():
        line = line.strip()
        if line.startswith("["):
            section = line.strip("[]").strip()
        elif section == "imu" and line.split("=")[0].strip() == "noise_profile":
            return line.split("=", 1)[1].strip().strip("'\"")
    return "kalibr"


def noise_sigma_runs(rows):
    """[(dataset, profile, variant, sigma_max, sigma_min)] of the VIO runs: the first NOISE_EVENTS
    /marg events, lowest seed per (dataset, profile, variant)."""
    chosen = {}
    for r in rows:
        if not r["dataset"].startswith(("euroc/", "tumvi/")) or not os.path.isfile(r["_path"]):
            continue
        try:
            run = mr.read_run(r["_path"])
        except (OSError, KeyError, mr.SchemaError) as e:
            print("warning: cannot read %s: %s" % (r["_path"], e), file=sys.stderr)
            continue
        if run.mode != "vio":
            continue
        key = (r["dataset"], noise_profile(run.attrs.get("config_toml", "")), run.variant)
        if key in chosen and int(chosen[key][0]) <= int(r["seed"]):
            continue
        sig_max = np.asarray(run.marg["sigma_max"], float)[:NOISE_EVENTS]
        sig_min = np.asarray(run.marg["sigma_min"], float)[:NOISE_EVENTS]
        chosen[key] = (r["seed"], sig_max, sig_min)
    return [(d, p, v, mx, mn) for (d, p, v), (_, mx, mn) in sorted(chosen.items())]


def plot_noise_sigma(runs, out, written):
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, j, name in ((axes[0], 3, r"$\sigma_{\max}(H_m)$"), (axes[1], 4, r"$\sigma_{\min}(H_m)$")):
        for profile, color in PROFILE_COLORS.items():
            curves = [r[j] for r in runs if r[1] == profile and len(r[j])]
            for c in curves:
                ax.plot(np.arange(1, len(c) + 1), c, color=color, lw=0.6, alpha=0.45)
            if curves:
                n = min(len(c) for c in curves)
                median = np.median(np.vstack([c[:n] for c in curves]), axis=0)
                ax.plot(np.arange(1, n + 1), median, color=color, lw=2.2,
                        label="%s (median of %d runs)" % (profile, len(curves)))
        ax.set_yscale("log" if j == 3 else "symlog", **({} if j == 3 else dict(linthresh=LINTHRESH)))
        ax.set_xlabel("marginalization event")
        ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
        ax.set_ylabel(name + " of the prior")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    variants = sorted({r[2] for r in runs})
    fig.suptitle("Prior eigenvalues at the first %d marginalizations, IMU noise profiles (%s, %d "
                 "sequences)" % (NOISE_EVENTS, ", ".join(variants), len({r[0] for r in runs})))
    fig.tight_layout()
    save(fig, out, "noise_sigma", written)
    path = os.path.join(out, "noise_sigma.csv")
    text = "dataset,profile,variant,event,sigma_max,sigma_min\n" + "".join(
        "%s,%s,%s,%d,%.17g,%.17g\n" % (d, p, v, k + 1, mx[k], mn[k])
        for d, p, v, mx, mn in runs for k in range(len(mx)))
    atomic_save.write_text(path, text)
    written.append(path)


def save(fig, out, name, written):
    for ext in ("png", "pdf"):
        path = os.path.join(out, "%s.%s" % (name, ext))
        atomic_save.savefig(fig, path, dpi=150, bbox_inches="tight")
        written.append(path)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("dirs", nargs="+", help="sweep folders (with index.csv)")
    parser.add_argument("--out", required=True)
    parser.add_argument("--vio-dataset", default="euroc/MH_01_easy")
    parser.add_argument("--vo-dataset", default="kitti/10")
    parser.add_argument("--figures",
                        default="fig1,fig4,fig4_yaw,fig5,fig6,fig7,sparsify,ba_convergence,"
                        "ba_profile")
    args = parser.parse_args()
    figures = set(args.figures.split(","))
    try:
        rows = read_rows(args.dirs)
    except mr.SchemaError as e:
        print("plot_paper.py: %s" % e, file=sys.stderr)
        return 1
    os.makedirs(args.out, exist_ok=True)
    written = []
    # `marglab ba` runs (index column kind = "ba") have figures of their own (ba_figures.py).
    ba_figures.plot(plt, [r for r in rows if r.get("kind") == "ba"], figures, args.out, save,
                    written)
    rows = [r for r in rows if r.get("kind") != "ba"]

    vio = pick_dataset(rows, args.vio_dataset, ("euroc/", "tumvi/"))
    vio_runs = select(rows, vio) if vio else []
    if figures & {"fig1", "fig4", "fig4_yaw"} and not vio_runs:
        print("skipped fig1, fig4, fig4_yaw: no headline runs on EuRoC / TUM-VI")
    if vio_runs:
        s = slug(vio)
        if "fig1" in figures:
            fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 9),
                                              gridspec_kw=dict(height_ratios=[3, 2]))
            plot_trajectories(top, vio_runs, "%s: trajectories (top-down)" % vio)
            plot_sigma_min(bottom, vio_runs, r"%s: smallest eigenvalue of the prior" % vio)
            fig.tight_layout()
            save(fig, args.out, "fig1_" + s, written)
        if "fig4" in figures:
            fig = plt.figure(figsize=(10, 6.5))
            plot_dEm(fig, vio_runs, r"%s: prior cost change $\Delta E_m$ along gauge and random "
                                    "directions" % vio)
            save(fig, args.out, "fig4_dEm_" + s, written)
        if "fig4_yaw" in figures:
            plot_yaw(seed_runs(rows, vio), vio, args.out, written)

    vo = pick_dataset(rows, args.vo_dataset, ("kitti/",))
    vo_runs = select(rows, vo) if vo else []
    if figures & {"fig5", "fig6", "fig7"} and not vo_runs:
        print("skipped fig5, fig6, fig7: no headline runs on KITTI")
    if vo_runs:
        s = slug(vo)
        if "fig5" in figures:
            fig = plt.figure(figsize=(10, 6.5))
            plot_dEm(fig, vo_runs, r"%s: prior cost change $\Delta E_m$ along gauge and random "
                                   "directions" % vo)
            save(fig, args.out, "fig5_dEm_" + s, written)
        if "fig6" in figures:
            fig, ax = plt.subplots(figsize=(8, 4))
            plot_sigma_min(ax, vo_runs, "%s: smallest eigenvalue of the prior" % vo)
            fig.tight_layout()
            save(fig, args.out, "fig6_sigma_min_" + s, written)
        if "fig7" in figures:
            fig, ax = plt.subplots(figsize=(7, 7))
            plot_trajectories(ax, vo_runs, "%s: trajectories (top-down)" % vo)
            fig.tight_layout()
            save(fig, args.out, "fig7_trajectory_" + s, written)

    if "sparsify" in figures:
        runs = nfr_runs(rows)
        if runs:
            plot_sparsify(runs, args.out, written)
        else:
            print("skipped sparsify: no nfr runs (results attribute marg_strategy)")

    if "noise_sigma" in figures:
        runs = noise_sigma_runs(rows)
        if runs:
            plot_noise_sigma(runs, args.out, written)
        else:
            print("skipped noise_sigma: no VIO runs")

    for path in written:
        print("wrote", path)
    if not written:
        print("no figure written: the sweep has no headline runs (%s) and no ba runs"
              % ", ".join(HEADLINE))
        return 1
    return 0


if __name__ == "__main__":
    atomic_save.run_main(main, "plot_paper.py")
