#!/usr/bin/env python3
"""Fig. 1 analog for the preconditioned storages (issue #31 §3, docs/preconditioned_storage.md):
the smallest eigenvalue of the gauge-free prior at every marginalization, relative to the
largest, for each variant (and override) of one dataset in the sweep folders.

Usage: plot_preconditioned.py FOLDER [FOLDER ...] --dataset euroc/MH_01_easy
                              [--dataset kitti/00 ...] [--seed 1] [--frames 600] --out DIR

One figure per dataset, DIR/sigma_min_<dataset>.png: top σ_min (symlog axis, linear within
±1e-8 as in plot_paper.py's Fig. 1), bottom σ_min/σ_max (symlog, linear within ±1e-9; 0 for the
exact prior, about ±ε of the precision from rounding, an indefinite prior below). A run that
failed ends in an ×.
"""
import argparse
import csv
import os
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import atomic_save  # noqa: E402

STYLE = {
    "ns-qr-sqrt-f32": dict(color="tab:green", lw=1.2),
    "sc-sc-sq-f32": dict(color="tab:red", lw=1.2),
    "sc-sc-sqp-f32": dict(color="tab:purple", lw=1.2),
    "ns-sc-sqp-f32": dict(color="tab:brown", lw=1.0, ls="--"),
    "sc-sc-sqj-f32": dict(color="tab:orange", lw=1.0, ls=":"),
    "sc-sc-sqp-f64": dict(color="tab:blue", lw=1.0),
    "sc-sc-sqrtp-f32": dict(color="tab:olive", lw=1.0, ls="-."),
}


def runs_of(folders, dataset, seed, frames):
    for folder in folders:
        with open(os.path.join(folder, "index.csv"), newline="") as f:
            for row in csv.DictReader(f):
                if row["dataset"] == dataset and row["seed"] == seed and row["frames"] == frames:
                    path = os.path.join(folder, row["results"])
                    if os.path.exists(path):
                        yield row, path


def plot(folders, dataset, seed, frames, out):
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    for row, path in runs_of(folders, dataset, seed, frames):
        with h5py.File(path, "r") as f:
            t = np.asarray(f["marg/t_ns"], float) * 1e-9
            lo, hi = np.asarray(f["marg/sigma_min"]), np.asarray(f["marg/sigma_max"])
        if len(t) == 0:
            continue
        t -= t[0]
        style = dict(STYLE.get(row["variant"], {}))
        label = row["variant"]
        if row.get("override"):
            label += " " + row["override"]
            style.update(lw=0.8, alpha=0.45, zorder=1)
        top.plot(t, lo, label=label, **style)
        bottom.plot(t, lo / hi, **style)
        if row["status"] != "ok":
            top.plot(t[-1], lo[-1], "x", color=style.get("color", "k"), ms=9)
            bottom.plot(t[-1], lo[-1] / hi[-1], "x", color=style.get("color", "k"), ms=9)
    top.set_yscale("symlog", linthresh=1e-8)
    bottom.set_yscale("symlog", linthresh=1e-9)
    for ax in (top, bottom):
        ax.axhspan(-1e-8 if ax is top else -1e-9, 1e-8 if ax is top else 1e-9, color="0.9")
        ax.grid(alpha=0.3)
    top.set_ylabel("σ_min of the gauge-free prior")
    bottom.set_ylabel("σ_min / σ_max")
    bottom.set_xlabel("time since the first marginalization [s]")
    top.set_title(f"{dataset}, seed {seed}, {frames if frames != '0' else 'all'} frames")
    top.legend(fontsize=8, ncol=2)
    fig.tight_layout()
    name = "sigma_min_" + dataset.replace("/", "-") + ".png"
    atomic_save.savefig(fig, os.path.join(out, name), dpi=110)
    plt.close(fig)
    return name


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folders", nargs="+")
    parser.add_argument("--dataset", action="append", required=True)
    parser.add_argument("--seed", default="1")
    parser.add_argument("--frames", default="600")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    for dataset in args.dataset:
        print(os.path.join(args.out, plot(args.folders, dataset, args.seed, args.frames, args.out)))


if __name__ == "__main__":
    main()
