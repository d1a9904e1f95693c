#!/usr/bin/env python3
"""What `marglab tables` cannot make for the preconditioned storages (issue #31 §3,
docs/preconditioned_storage.md), because it needs the runs' HDF5 files (not committed):

Usage: preconditioned_table.py FOLDER [FOLDER ...] --out DIR

preconditioned_sigma.md / .csv: per sequence, variant and override of the whole-sequence runs,
the most negative ratio of the smallest to the largest eigenvalue of the gauge-free prior over the
run (/marg sigma_min, sigma_max; 0 for the exact prior, about ±ε of the precision from rounding, an
indefinite prior below), median over the seeds whose results file is in its folder, with their
number; "–" without one.

preconditioned_short.md / .csv: the runs over the first N frames (a sweep's short group), per
sequence and variant: ATE over the seeds ("mean ± std (n)", then "x k/n" when k of n failed), the
frames where the failed runs stopped, and the σ_min/σ_max above.

The ATE of the whole-sequence runs, with seed statistics, and their failure frames come from
`marglab tables` (preconditioned.md, preconditioned_failures.md); times from
`marglab bench --variant`.
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

ORDER = ["ns-qr-sqrt-f32", "sc-sc-sq-f32", "sc-sc-sqrt-f32", "sc-sc-sqp-f32", "ns-sc-sqp-f32",
         "sc-sc-sqj-f32", "sc-sc-sqrtp-f32", "sc-sc-sqp-f64"]


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


def ratio_cell(runs):
    ratios = [x for x in (worst_ratio(r) for r in runs) if x is not None]
    return f"{statistics.median(ratios):.1e} ({len(ratios)})" if ratios else "–"


def ate_cells(runs):
    ok = [float(r["ate_rmse"]) for r in runs if r["status"] == "ok"]
    failed = [r for r in runs if r["status"] != "ok"]
    ate = tc.seed_cell(ok, len(failed), len(runs), 4) if runs else "–"
    frames = ", ".join(sorted((r["failure_frame"] or "?" for r in failed),
                              key=lambda f: int(f) if f.isdigit() else -1)) or "–"
    return ate, frames


def sequences(rows):
    return sorted({r["dataset"] for r in rows}, key=lambda d: (d.startswith("kitti"), d))


def variants(rows):
    present = {r["variant"] for r in rows}
    return [v for v in ORDER if v in present] + sorted(present - set(ORDER))


def sigma_table(whole):
    rows = [["sequence", "variant", "override", "σ_min/σ_max (seeds)"]]
    for d in sequences(whole):
        for v in variants(whole):
            for o in sorted({r["override"] for r in whole}):
                runs = [r for r in whole if (r["dataset"], r["variant"], r["override"]) == (d, v, o)]
                if runs:
                    rows.append([d, v, o or "–", ratio_cell(runs)])
    return rows


def short_table(short):
    rows = [["sequence", "variant", "frames", "ATE [m]", "fail at", "σ_min/σ_max (seeds)"]]
    for d in sequences(short):
        for v in variants(short):
            runs = [r for r in short if r["dataset"] == d and r["variant"] == v]
            if runs:
                rows.append([d, v, runs[0]["frames"], *ate_cells(runs), ratio_cell(runs)])
    return rows


def markdown(title, rows, note):
    lines = [f"### {title}", "", "| " + " | ".join(rows[0]) + " |",
             "|" + "|".join("---" for _ in rows[0]) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows[1:]]
    return "\n".join(lines) + "\n\n" + note + "\n"


NOTE = ("σ_min/σ_max: most negative ratio of the gauge-free prior's smallest to largest eigenvalue "
        "over the run, median over the seeds whose results file was present (their number); 0 "
        "exactly, ±1e-7 f32 rounding, below: an indefinite prior.")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folders", nargs="+")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    rows = [r for d in args.folders for r in read_index(d)]
    whole = [r for r in rows if r["frames"] == "0"]
    short = [r for r in rows if r["frames"] != "0"]
    os.makedirs(args.out, exist_ok=True)
    where = "Folders: " + ", ".join(args.folders) + "."
    if whole:
        table = sigma_table(whole)
        tc.write_csv(os.path.join(args.out, "preconditioned_sigma.csv"), table)
        tc.write_text(os.path.join(args.out, "preconditioned_sigma.md"),
                      markdown("Preconditioned Hessian storage: how indefinite the stored prior "
                               "becomes, whole sequences", table, NOTE + " " + where))
    if short:
        table = short_table(short)
        tc.write_csv(os.path.join(args.out, "preconditioned_short.csv"), table)
        tc.write_text(os.path.join(args.out, "preconditioned_short.md"),
                      markdown("Preconditioned Hessian storage: the short group (first N frames)",
                               table, "ATE: mean ± sample std (n ok runs) over the seeds, `x k/n`: "
                               "k of n runs failed (left out of the mean); fail at: frames where "
                               "they stopped. " + NOTE + " " + where))


if __name__ == "__main__":
    main()
