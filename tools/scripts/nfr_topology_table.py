#!/usr/bin/env python3
"""The nfr topology comparison of a sweep (experiments/nfr_topology.toml, issue #19 section 3): ATE
and KLD per keyframe-marginalization choice — discard, dense, nfr with each topology — on the same
(sequence, seed) pairs.

Usage: nfr_topology_table.py SWEEP_DIR   (writes SWEEP_DIR/tables/topology.md and topology.csv)

Per run: ATE RMSE (index.csv) and, from /sparsify, the mean KLD over the events whose factors
replaced the prior, the share of such events, the mean nnz_sparse / nnz_dense and the blanket size
(poses, landmarks), and the median ratio of the information along the gauge directions of what
replaced the prior to the dense prior's (/sparsify info_sparse / info_dense). Against discard: per (sequence, seed) pair, whether the ATE is lower, and the
geometric mean of ATE / ATE(discard) over all pairs. Needs numpy, h5py and pandas
(marglab_results.py).

Why not `marglab tables`: a cell there reduces one number per run over the seeds of one dataset ×
column (core/experiment/table_specs.h); the comparison against discard here is paired — the same
(sequence, seed) of two overrides — and the information ratios are medians over the gauge
directions of every /sparsify event.
"""
import csv
import math
import os
import statistics
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import marglab_results as mr  # noqa: E402
from table_common import mean, seed_cell, write_csv, write_text  # noqa: E402

ORDER = ["discard", "dense", "nfr-paper", "nfr-joint-states", "nfr-relative-pose"]


def load(sweep):
    """{(override, dataset, seed): run dict} from index.csv and the results files."""
    runs = {}
    with open(os.path.join(sweep, "index.csv"), newline="") as f:
        for row in csv.DictReader(f):
            run = {"status": row["status"], "ate": float("nan"), "kld": float("nan"),
                   "recovered": float("nan"), "nnz": float("nan"), "poses": float("nan"),
                   "landmarks": float("nan"), "events": 0}
            path = os.path.join(sweep, row["results"])
            if row["status"] == "ok" and os.path.exists(path):
                run["ate"] = float(row["ate_rmse"])
                sp = mr.read_run(path).sparsify
                if len(sp):
                    rec = np.asarray(sp["recovered"], dtype=bool)
                    kld = np.asarray(sp["kld"], dtype=float)[rec]
                    run["events"] = len(sp)
                    run["recovered"] = float(rec.mean())
                    run["kld"] = float(np.nanmean(kld)) if kld.size else float("nan")
                    run["nnz"] = float(np.mean(np.asarray(sp["nnz_sparse"], dtype=float) /
                                               np.asarray(sp["nnz_dense"], dtype=float)))
                    run["poses"] = float(np.mean(sp["n_blanket_poses"]))
                    run["landmarks"] = float(np.mean(sp["n_blanket_landmarks"]))
                    run.update(information_ratios(sp))
            runs[(row["override"], row["dataset"].split("/")[-1], int(row["seed"]))] = run
    return runs


def information_ratios(sp):
    """Median over the events of εᵀΛ_s ε / εᵀΛ_t ε per gauge direction (files with the /sparsify
    information columns; {} otherwise)."""
    if "info_dense_x" not in sp:
        return {}
    return {"info_" + d: float(np.median(np.asarray(sp["info_sparse_" + d], dtype=float) /
                                         np.asarray(sp["info_dense_" + d], dtype=float)))
            for d in mr.DEM_DIRECTIONS}


def information_lines(runs, overrides):
    """Median information ratio per strategy and direction (mean over the runs' medians)."""
    lines = ["| strategy | " + " | ".join(mr.DEM_DIRECTIONS) + " |",
             "|---|" + "---:|" * len(mr.DEM_DIRECTIONS)]
    for o in overrides:
        sel = [r for k, r in runs.items() if k[0] == o and "info_x" in r]
        if sel:
            lines.append(f"| {o} | " + " | ".join(
                fmt(mean([r["info_" + d] for r in sel]), 2) for d in mr.DEM_DIRECTIONS) + " |")
    return lines


def against_discard(runs, override):
    """(pairs with a lower ATE than discard, pairs compared, geometric-mean ATE ratio)."""
    better, ratios = 0, []
    for (o, dataset, seed), r in runs.items():
        d = runs.get(("discard", dataset, seed))
        if o != override or d is None or not (np.isfinite(r["ate"]) and np.isfinite(d["ate"])):
            continue
        better += r["ate"] < d["ate"]
        ratios.append(math.log(r["ate"] / d["ate"]))
    return better, len(ratios), math.exp(statistics.fmean(ratios)) if ratios else float("nan")


def fmt(x, digits):
    return f"{x:.{digits}f}" if np.isfinite(x) else "–"


def summary_lines(runs, overrides):
    lines = ["| strategy | ok | mean ATE [m] | < discard | ATE / discard (geo. mean) | "
             "KLD [nats] | recovered | nnz sparse / dense | blanket poses | blanket landmarks |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for o in overrides:
        sel = [r for k, r in runs.items() if k[0] == o]
        ok = [r for r in sel if r["status"] == "ok"]
        better, n, geo = against_discard(runs, o)
        vs = "–" if o == "discard" else f"{better} / {n}"
        lines.append(
            f"| {o} | {len(ok)}/{len(sel)} | {fmt(mean([r['ate'] for r in ok]), 4)} | {vs} | "
            f"{'–' if o == 'discard' else fmt(geo, 3)} | {fmt(mean([r['kld'] for r in ok]), 2)} | "
            f"{fmt(mean([r['recovered'] for r in ok]), 3)} | {fmt(mean([r['nnz'] for r in ok]), 3)} | "
            f"{fmt(mean([r['poses'] for r in ok]), 2)} | {fmt(mean([r['landmarks'] for r in ok]), 1)} |")
    return lines


def per_sequence_lines(runs, overrides):
    datasets = sorted({k[1] for k in runs})
    lines = ["| sequence | " + " | ".join(overrides) + " |",
             "|---|" + "---:|" * len(overrides)]
    for d in datasets:
        cells = []
        for o in overrides:
            sel = [r for k, r in runs.items() if k[0] == o and k[1] == d]
            ates = [r["ate"] for r in sel if np.isfinite(r["ate"])]
            cells.append(seed_cell(ates, sum(r["status"] == "failed" for r in sel), len(sel), 4))
        lines.append(f"| {d} | " + " | ".join(cells) + " |")
    return lines


def main():
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[4], file=sys.stderr)
        return 2
    sweep = sys.argv[1]
    runs = load(sweep)
    present = {k[0] for k in runs}
    overrides = [o for o in ORDER if o in present] + sorted(present - set(ORDER))
    seeds = sorted({k[2] for k in runs})
    lines = ["# nfr topologies against discard and dense (issue #19, section 3)", "",
             f"Sweep `{os.path.basename(os.path.normpath(sweep))}`: {len(runs)} runs, seeds "
             f"{', '.join(map(str, seeds))}; ATE RMSE in m after SE(3) alignment.", "",
             "KLD: mean D_KL(Λ_t ‖ Λ_s) per keyframe event whose recovered factors replaced the "
             "dense prior (/sparsify kld; joint-states: its joint factor keeps the state block "
             "exact); recovered: share of such events; < discard: (sequence, seed) pairs with a "
             "lower ATE than discard.", ""]
    lines += summary_lines(runs, overrides)
    lines += ["", "Per sequence: mean ± sample std of the ATE over the seeds, (n) runs with an "
              "ATE; x k/n: k of n runs failed; runs not yet done (status pending) are left out.",
              ""]
    lines += per_sequence_lines(runs, overrides)
    info = information_lines(runs, overrides)
    if len(info) > 2:
        lines += ["", "Information along the window's rigid motions: εᵀΛ_s ε / εᵀΛ_t ε of what "
                  "replaced the dense prior against the dense prior, along the unit gauge "
                  "directions over the blanket (x, y, z, roll, pitch, yaw about the poses' centroid, "
                  "landmarks moved with them; random: one random unit direction); median over a "
                  "run's events, mean over its runs. 1: as the dense prior; above 1: more confident.",
                  ""]
        lines += info
    out_dir = os.path.join(sweep, "tables")
    os.makedirs(out_dir, exist_ok=True)
    columns = ["info_" + d for d in mr.DEM_DIRECTIONS]
    rows = [["strategy", "dataset", "seed", "status", "ate_rmse", "kld_mean", "recovered_share",
             "nnz_ratio", "blanket_poses", "blanket_landmarks"] + [c + "_ratio" for c in columns]]
    rows += [[o, d, s, r["status"], r["ate"], r["kld"], r["recovered"], r["nnz"], r["poses"],
              r["landmarks"]] + [r.get(c, float("nan")) for c in columns]
             for (o, d, s), r in sorted(runs.items())]
    write_csv(os.path.join(out_dir, "topology.csv"), rows)
    write_text(os.path.join(out_dir, "topology.md"), "\n".join(lines) + "\n")
    print(os.path.join(out_dir, "topology.md"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
