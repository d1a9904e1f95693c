#!/usr/bin/env python3
"""Table "Preconditioned Hessian storage" (issue #31 §3, docs/preconditioned_storage.md).

Usage: preconditioned_table.py --new DIR [DIR ...] --base DIR [DIR ...] --out DIR
                               [--sqrtp DIR --ablation DIR [DIR ...]]

--new: sweep folders of experiments/preconditioned_subset.toml (one per seed); --base: the
committed folders of the same seeds with the baselines (results/paper_seeds_sK). Writes
preconditioned.md / .csv (whole sequences) and preconditioned_short.md / .csv (the `short` group:
every new variant and the two baselines on 600 frames) into --out.

Cells over seeds: "mean ± std (n)" of the ATE [m] of the runs that finished ok, then "x k/n" when k
of n failed (table_common.seed_cell); "fail at" the frames where the failed runs stopped;
"σ_min/σ_max": the most negative ratio of the smallest to the largest eigenvalue of the gauge-free
prior over a run (/marg sigma_min, sigma_max; the exact prior has 0 there, rounding gives ±ε,
an indefinite prior below −ε), median over the seeds whose results file is present (the HDF5
runs are not committed: "–" without them).

preconditioned_sqrtp.md / .csv (with --sqrtp, the folder of experiments/preconditioned_sqrtp.toml,
and --ablation, sweep folders holding ns-qr-sqrt-f32 and sc-sc-sqrt-f32 of the same seed, e.g.
results/paper_vio results/paper_vo): the square-root prior made by the preconditioned LDLT against
the same LDLT without preconditioning and against √-f32, whole sequences.

preconditioned_timing.md / .csv: per short-group run that finished ok, the optimization time per
LM iteration (Σ /frames t_opt_s ÷ Σ lm_iterations) and the time per marginalization (Σ t_marg_s
÷ the number of /marg events), median over the seeds, in ms. Wall-clock times on a shared
machine: compare within one table only.
"""
import argparse
import csv
import os
import statistics
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import table_common as tc  # noqa: E402

NEW = "sc-sc-sqp-f32"
BASE = ["ns-qr-sqrt-f32", "sc-sc-sq-f32"]
SHORT = ["ns-qr-sqrt-f32", "sc-sc-sq-f32", "sc-sc-sqp-f32", "ns-sc-sqp-f32", "sc-sc-sqj-f32",
         "sc-sc-sqp-f64"]


def read_index(folder):
    with open(os.path.join(folder, "index.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        r["_folder"] = folder
    # Runs still pending or running (a sweep under way) are left out.
    return [r for r in rows if r["status"] in ("ok", "failed")]


def worst_ratio(row):
    path = os.path.join(row["_folder"], row["results"])
    if not row.get("results") or not os.path.exists(path):
        return None
    with h5py.File(path, "r") as f:
        lo, hi = np.asarray(f["marg/sigma_min"]), np.asarray(f["marg/sigma_max"])
    ok = np.isfinite(lo) & np.isfinite(hi) & (hi > 0)
    return float(np.min(lo[ok] / hi[ok])) if ok.any() else None


def cells(runs):
    ok = [float(r["ate_rmse"]) for r in runs if r["status"] == "ok"]
    failed = [r for r in runs if r["status"] != "ok"]
    ate = tc.seed_cell(ok, len(failed), len(runs), 4) if runs else "–"
    frames = ", ".join(sorted((r["failure_frame"] or "?" for r in failed),
                              key=lambda f: int(f) if f.isdigit() else -1)) or "–"
    ratios = [x for x in (worst_ratio(r) for r in runs) if x is not None]
    ratio = f"{statistics.median(ratios):.1e}" if ratios else "–"
    return ate, frames, ratio


def select(rows, dataset, variant, frames):
    return [r for r in rows
            if r["dataset"] == dataset and r["variant"] == variant and r["frames"] == frames]


def short_name(dataset):
    return dataset.replace("euroc/", "").replace("kitti/", "kitti ")


def whole_table(new, base):
    datasets = sorted({r["dataset"] for r in new if r["frames"] == "0"},
                      key=lambda d: (d.startswith("kitti"), d))
    header = ["sequence", "√-f32 ATE (ns-qr-sqrt-f32)", "VIO/VO-32 ATE (sc-sc-sq-f32)",
              "fail at", "sqp-f32 ATE (sc-sc-sqp-f32)", "fail at", "σ_min/σ_max sqp-f32"]
    rows = [header]
    for d in datasets:
        sqrt_ate, _, _ = cells(select(base, d, BASE[0], "0"))
        sq_ate, sq_frames, _ = cells(select(base, d, BASE[1], "0"))
        sqp_ate, sqp_frames, sqp_ratio = cells(select(new, d, NEW, "0"))
        rows.append([short_name(d), sqrt_ate, sq_ate, sq_frames, sqp_ate, sqp_frames, sqp_ratio])
    return rows


def short_table(new):
    datasets = sorted({r["dataset"] for r in new if r["frames"] != "0"},
                      key=lambda d: (d.startswith("kitti"), d))
    rows = [["sequence", "variant", "ATE [m]", "fail at", "σ_min/σ_max"]]
    for d in datasets:
        for v in SHORT:
            runs = [r for r in new if r["dataset"] == d and r["variant"] == v and r["frames"] != "0"]
            if runs:
                rows.append([short_name(d), v, *cells(runs)])
    return rows


def timing(row):
    path = os.path.join(row["_folder"], row["results"])
    if row["status"] != "ok" or not os.path.exists(path):
        return None
    with h5py.File(path, "r") as f:
        iters = float(np.sum(f["frames/lm_iterations"]))
        t_opt = float(np.sum(f["frames/t_opt_s"]))
        t_marg = float(np.sum(f["frames/t_marg_s"]))
        n_marg = len(f["marg/frame_index"])
    return 1e3 * t_opt / max(iters, 1.0), 1e3 * t_marg / max(n_marg, 1)


def timing_table(new):
    datasets = sorted({r["dataset"] for r in new if r["frames"] != "0"},
                      key=lambda d: (d.startswith("kitti"), d))
    rows = [["sequence", "variant", "ms / LM iteration", "ms / marginalization", "runs"]]
    for d in datasets:
        for v in SHORT:
            t = [x for x in (timing(r) for r in new
                             if r["dataset"] == d and r["variant"] == v and r["frames"] != "0")
                 if x is not None]
            if t:
                rows.append([short_name(d), v, f"{statistics.median(a for a, _ in t):.2f}",
                             f"{statistics.median(b for _, b in t):.2f}", str(len(t))])
    return rows


def sqrtp_table(sqrtp, ablation):
    datasets = sorted({r["dataset"] for r in sqrtp}, key=lambda d: (d.startswith("kitti"), d))
    seeds = {r["seed"] for r in sqrtp}
    ablation = [r for r in ablation if r["seed"] in seeds]
    rows = [["sequence", "√-f32 (ns-qr-sqrt-f32)", "sc-sc-sqrt-f32", "sc-sc-sqrtp-f32",
             "sqrtp ÷ √-f32"]]
    for d in datasets:
        ref = [r for r in ablation if r["dataset"] == d and r["variant"] == "ns-qr-sqrt-f32"]
        plain = [r for r in ablation if r["dataset"] == d and r["variant"] == "sc-sc-sqrt-f32"]
        new = [r for r in sqrtp if r["dataset"] == d]
        ratio = "–"
        if len(ref) == len(new) == 1 and ref[0]["status"] == new[0]["status"] == "ok":
            ratio = f"{float(new[0]['ate_rmse']) / float(ref[0]['ate_rmse']):.2f}"
        rows.append([short_name(d), cells(ref)[0], cells(plain)[0], cells(new)[0], ratio])
    return rows


def markdown(title, rows, note):
    lines = [f"### {title}", "", "| " + " | ".join(rows[0]) + " |",
             "|" + "|".join("---" for _ in rows[0]) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows[1:]]
    return "\n".join(lines) + "\n\n" + note + "\n"


NOTE = ("ATE: mean ± sample std (n ok runs) over the seeds, `x k/n`: k of n runs failed numerically "
        "(left out of the mean); fail at: frames where they stopped; σ_min/σ_max: most negative "
        "ratio of the gauge-free prior's smallest to largest eigenvalue over the run, median over "
        "seeds (0 exactly; ±1e-7 is f32 rounding).")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--new", nargs="+", required=True)
    parser.add_argument("--base", nargs="+", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--sqrtp")
    parser.add_argument("--ablation", nargs="+", default=[])
    args = parser.parse_args()
    new = [r for d in args.new for r in read_index(d)]
    base = [r for d in args.base for r in read_index(d)]
    seeds = sorted({r["seed"] for r in new}, key=int)
    base = [r for r in base if r["seed"] in seeds]
    os.makedirs(args.out, exist_ok=True)
    whole = whole_table(new, base)
    short = short_table(new)
    where = f"Seeds {', '.join(seeds)}; new runs: {', '.join(args.new)}; baselines: {', '.join(args.base)}."
    tc.write_csv(os.path.join(args.out, "preconditioned.csv"), whole)
    tc.write_text(os.path.join(args.out, "preconditioned.md"),
                  markdown("Preconditioned Hessian storage: whole sequences", whole,
                           NOTE + " " + where))
    tc.write_csv(os.path.join(args.out, "preconditioned_short.csv"), short)
    tc.write_text(os.path.join(args.out, "preconditioned_short.md"),
                  markdown("Preconditioned Hessian storage: all new variants, first 600 frames",
                           short, NOTE + " " + where))
    if args.sqrtp:
        rows = sqrtp_table(read_index(args.sqrtp), [r for d in args.ablation for r in read_index(d)])
        tc.write_csv(os.path.join(args.out, "preconditioned_sqrtp.csv"), rows)
        tc.write_text(os.path.join(args.out, "preconditioned_sqrtp.md"),
                      markdown("Square-root prior from the preconditioned LDLT (PC-SRIF's "
                               "pipeline), whole sequences", rows,
                               "ATE [m]; x: failed. sqrtp: " + args.sqrtp + "; √-f32 and "
                               "sc-sc-sqrt-f32: " + ", ".join(args.ablation) + " (same seed)."))
    times = timing_table(new)
    tc.write_csv(os.path.join(args.out, "preconditioned_timing.csv"), times)
    tc.write_text(os.path.join(args.out, "preconditioned_timing.md"),
                  markdown("Preconditioned Hessian storage: time per LM iteration and per "
                           "marginalization, first 600 frames (runs that finished)", times,
                           "Median over the seeds of Σ t_opt_s / Σ lm_iterations and Σ t_marg_s / "
                           "events, wall clock on a shared 2-core machine. " + where))


if __name__ == "__main__":
    main()
