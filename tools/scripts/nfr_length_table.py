#!/usr/bin/env python3
"""ATE against run length for discard and nfr on the same (sequence, seed) pairs
(experiments/nfr_length.toml, issue #19 section 3).

Usage: nfr_length_table.py SWEEP_DIR   (writes SWEEP_DIR/tables/length.md and length.csv)

A run is causal: frames 1..N of a whole run are bit for bit the N-frame run (checked by
test/cli/nfr_length_agrees.py). So the ATE of an N-frame run is the ATE of the first N frames of
the whole run, aligned on their own: Umeyama without scale, with the reflection fix, as
core/diagnostics/ate.h (check_results.umeyama_rmse), over the frames whose p_est and p_gt are both
finite. Per prefix length: the (sequence, seed) pairs where nfr's ATE is below discard's, and
the geometric mean of ATE(nfr) / ATE(discard). Per 400-frame segment, each aligned on its own, the
same comparison of local accuracy: does nfr lose locally late in a run, or only in accumulated
drift? Needs numpy, h5py and pandas (marglab_results.py).
"""
import csv
import math
import os
import statistics
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import marglab_results as mr  # noqa: E402
from check_results import umeyama_rmse  # noqa: E402

PREFIXES = [200, 400, 800, 1200, 1600]  # frames; "whole" is added per run
SEGMENT = 400                           # frames per segment of the local comparison


def aligned_rmse(p_est, p_gt):
    """ATE RMSE after the rigid alignment of core/diagnostics/ate.h; NaN without pairs."""
    ok = np.all(np.isfinite(p_est), axis=1) & np.all(np.isfinite(p_gt), axis=1)
    return umeyama_rmse(p_est[ok], p_gt[ok])[0] if ok.any() else float("nan")


def prefix_ate(run, n):
    """ATE of the first n frames of `run` (a marglab_results.Run), aligned on their own."""
    return aligned_rmse(run.positions("p_est")[:n], run.positions("p_gt")[:n])


def segment_ates(run):
    """ATE of each whole SEGMENT-frame segment, each aligned on its own."""
    p_est, p_gt = run.positions("p_est"), run.positions("p_gt")
    return [aligned_rmse(p_est[k:k + SEGMENT], p_gt[k:k + SEGMENT])
            for k in range(0, len(p_est) - SEGMENT + 1, SEGMENT)]


def load(sweep):
    """{(override, dataset, seed): {"n": frames, "prefix": {L: ate}, "segments": [ate]}} of the
    runs that completed; a failed run is left out (with its pair)."""
    runs = {}
    for row in mr.read_index_rows(sweep):
        path = row["path"]
        if row["status"] != "ok" or not os.path.exists(path):
            continue
        run = mr.read_run(path)
        n = len(run.frames["t_ns"])
        prefix = {L: prefix_ate(run, L) for L in PREFIXES if L <= n}
        prefix["whole"] = prefix_ate(run, n)
        if not math.isclose(prefix["whole"], float(run.summary["ate_rmse"]), rel_tol=1e-9):
            raise SystemExit("%s: whole-run ATE %.17g here, %.17g in /summary"
                             % (path, prefix["whole"], float(run.summary["ate_rmse"])))
        runs[(row["override"], row["dataset"].split("/")[-1], int(row["seed"]))] = {
            "n": n, "prefix": prefix, "segments": segment_ates(run)}
    return runs


def pairs(runs):
    """[(dataset, seed, discard run, nfr run)] for the pairs where both completed."""
    out = []
    for (o, d, s), r in sorted(runs.items()):
        if o == "discard" and ("nfr", d, s) in runs:
            out.append((d, s, r, runs[("nfr", d, s)]))
    return out


def compare(values):
    """(nfr better, pairs, geometric mean of nfr / discard) over [(discard, nfr)] ATEs."""
    v = [(a, b) for a, b in values if np.isfinite(a) and np.isfinite(b) and a > 0]
    if not v:
        return 0, 0, float("nan")
    return (sum(b < a for a, b in v), len(v),
            math.exp(statistics.fmean(math.log(b / a) for a, b in v)))


def length_lines(ps):
    lines = ["| run length [frames] | nfr < discard | ATE(nfr) / ATE(discard), geo. mean |",
             "|---|---:|---:|"]
    for L in PREFIXES + ["whole"]:
        better, n, geo = compare([(d["prefix"][L], f["prefix"][L]) for _, _, d, f in ps
                                  if L in d["prefix"] and L in f["prefix"]])
        lines.append(f"| {L} | {better} / {n} | {geo:.3f} |")
    return lines


def segment_lines(ps):
    lines = ["| segment [frames] | nfr < discard | ATE(nfr) / ATE(discard), geo. mean |",
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


def pair_lines(ps):
    cols = PREFIXES + ["whole"]
    lines = ["| sequence | seed | frames | " + " | ".join(map(str, cols)) + " |",
             "|---|---:|---:|" + "---:|" * len(cols)]
    for d, s, dr, fr in ps:
        cells = [f"{fr['prefix'][L] / dr['prefix'][L]:.2f}" if L in dr["prefix"] else "–"
                 for L in cols]
        lines.append(f"| {d} | {s} | {dr['n']} | " + " | ".join(cells) + " |")
    return lines


def write_csv(path, runs):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["strategy", "dataset", "seed", "frames", "kind", "length_or_segment", "ate"])
        for (o, d, s), r in sorted(runs.items()):
            for L, ate in r["prefix"].items():
                w.writerow([o, d, s, r["n"], "prefix", L, repr(ate)])
            for k, ate in enumerate(r["segments"]):
                w.writerow([o, d, s, r["n"], "segment", k * SEGMENT, repr(ate)])


def main():
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[3], file=sys.stderr)
        return 2
    sweep = sys.argv[1]
    runs = load(sweep)
    ps = pairs(runs)
    lines = ["# nfr against discard by run length (issue #19, section 3)", "",
             f"Sweep `{os.path.basename(os.path.normpath(sweep))}`: {len(ps)} (sequence, seed) "
             "pairs where both runs completed. ATE RMSE of the first N frames of each run, "
             "aligned on their own (what an N-frame run reports).", ""]
    lines += length_lines(ps)
    lines += ["", f"Local accuracy: the ATE of each {SEGMENT}-frame segment, aligned on its own "
              "(pairs with that segment).", ""]
    lines += segment_lines(ps)
    lines += ["", "ATE(nfr) / ATE(discard) per pair and run length (below 1: nfr better).", ""]
    lines += pair_lines(ps)
    out_dir = os.path.join(sweep, "tables")
    os.makedirs(out_dir, exist_ok=True)
    write_csv(os.path.join(out_dir, "length.csv"), runs)
    with open(os.path.join(out_dir, "length.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print(os.path.join(out_dir, "length.md"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
