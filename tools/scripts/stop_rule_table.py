#!/usr/bin/env python3
"""The lm.stop_rule comparison of a sweep (experiments/stop_rule.toml): ATE and LM iterations per
frame, marglab vs basalt, with the seed noise to set the difference against.

Usage: stop_rule_table.py SWEEP_DIR   (writes SWEEP_DIR/tables/stop_rule.md and stop_rule.csv)

Per run: ATE RMSE (index.csv), mean LM iterations (linearizations) per frame and optimization time
per frame (the results file's /frames/lm_iterations and t_opt_total_s). Rule effect: the relative
ATE change basalt vs marglab of the same dataset, variant and seed. Seed noise: the relative ATE
change seed 2 vs seed 1 of the same dataset, variant and rule. Needs numpy and h5py.

Why not `marglab tables`: a cell there reduces one number per run over the seeds of one dataset ×
column (core/experiment/table_specs.h); the rule effect and the seed noise here are paired
differences between runs of two groups, and of two seeds, of the same dataset and variant.
"""
import csv
import os
import statistics
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from table_common import finite, write_csv, write_text  # noqa: E402


def load(sweep):
    runs = {}
    with open(os.path.join(sweep, "index.csv"), newline="") as f:
        for row in csv.DictReader(f):
            key = (row["group"].rstrip("0123456789"), row["dataset"], row["variant"], int(row["seed"]), row["override"])
            run = {"status": row["status"], "ate": float("nan"), "it": float("nan"),
                   "opt_ms": float("nan"), "failure_frame": row["failure_frame"]}
            path = os.path.join(sweep, row["results"])
            if row["status"] == "ok" and os.path.exists(path):
                run["ate"] = float(row["ate_rmse"])
                with h5py.File(path, "r") as h5:
                    it = np.asarray(h5["frames/lm_iterations"][()], dtype=float)
                run["it"] = float(it.mean()) if it.size else float("nan")
                run["opt_ms"] = 1e3 * float(row["t_opt_total_s"]) / max(1, int(row["n_frames"]))
            runs[key] = run
    return runs


def rel(a, b):
    return (a - b) / b if b > 0 and np.isfinite(a) and np.isfinite(b) else float("nan")


def summary_rows(runs):
    """Per group and variant: mean ATE, iterations and time per frame for each rule."""
    rows = []
    cells = sorted({(k[0], k[2]) for k in runs})
    for group, variant in cells:
        row = [group, variant]
        for rule in ("marglab", "basalt"):
            sel = [r for k, r in runs.items() if k[0] == group and k[2] == variant and k[4] == rule]
            ok = [r for r in sel if r["status"] == "ok"]
            row += [len(ok), len(sel),
                    statistics.fmean(finite([r["ate"] for r in ok])) if ok else float("nan"),
                    statistics.fmean(finite([r["it"] for r in ok])) if ok else float("nan"),
                    statistics.fmean(finite([r["opt_ms"] for r in ok])) if ok else float("nan")]
        rows.append(row)
    return rows


def effects(runs):
    """|relative ATE change| between the rules (same seed) and between the seeds (same rule)."""
    rule_effect, seed_noise = {}, {}
    for (group, dataset, variant, seed, rule), r in runs.items():
        if rule == "basalt":
            m = runs.get((group, dataset, variant, seed, "marglab"))
            if m:
                rule_effect.setdefault(group, []).append(abs(rel(r["ate"], m["ate"])))
        if seed == 2:
            s1 = runs.get((group, dataset, variant, 1, rule))
            if s1:
                seed_noise.setdefault(group, []).append(
                    abs(rel(r["ate"], 0.5 * (r["ate"] + s1["ate"]))) * 2)
    return rule_effect, seed_noise


def run_text(run, key, digits):
    """A run's value, or why it has none (failed at frame k, missing, pending)."""
    status = run.get("status", "missing")
    if status == "failed":
        return f"failed (frame {run.get('failure_frame', '?')})"
    if status != "ok":
        return status
    return f"{run[key]:.{digits}f}"


def main():
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    sweep = sys.argv[1]
    runs = load(sweep)
    out_dir = os.path.join(sweep, "tables")
    os.makedirs(out_dir, exist_ok=True)
    lines = ["# lm.stop_rule: marglab (default) vs basalt", "",
             f"Sweep `{sweep}`: {len(runs)} runs, "
             + ", ".join(f"{sum(r['status'] == st for r in runs.values())} {st}"
                         for st in sorted({r["status"] for r in runs.values()}))
             + ". ATE RMSE in m, LM iterations = linearizations "
             "per frame, opt = optimization time per frame (ms; machine shared and loaded, "
             "compare within a row only).", "",
             "| group | variant | ok marglab | ATE marglab | it/frame marglab | opt ms marglab | "
             "ok basalt | ATE basalt | it/frame basalt | opt ms basalt |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for g, v, nm, tm, am, im, om, nb, tb, ab, ib, ob in summary_rows(runs):
        lines.append(f"| {g} | {v} | {nm}/{tm} | {am:.4f} | {im:.2f} | {om:.2f} | {nb}/{tb} | "
                     f"{ab:.4f} | {ib:.2f} | {ob:.2f} |")
    rule_effect, seed_noise = effects(runs)
    lines += ["", "Relative ATE change: between the rules (same dataset, variant, seed) and "
              "between the seeds (same dataset, variant, rule); failed runs left out.", "",
              "| group | rule: median | rule: mean | rule: max | seed: median | seed: mean | "
              "seed: max |", "|---|---:|---:|---:|---:|---:|---:|"]
    for g in sorted(rule_effect):
        r, s = finite(rule_effect[g]), finite(seed_noise.get(g, []))
        def stats(x):
            return (statistics.median(x), statistics.fmean(x), max(x)) if x else (np.nan,) * 3
        a, b = stats(r), stats(s)
        lines.append(f"| {g} | {a[0]:.1%} | {a[1]:.1%} | {a[2]:.1%} | {b[0]:.1%} | {b[1]:.1%} | "
                     f"{b[2]:.1%} |")
    lines += ["", "## Per run", "",
              "| group | dataset | variant | seed | ATE marglab | ATE basalt | it marglab | "
              "it basalt |", "|---|---|---|---:|---:|---:|---:|---:|"]
    rows = [["group", "dataset", "variant", "seed", "rule", "status", "ate_rmse",
             "lm_iterations_per_frame", "opt_ms_per_frame"]]
    for k in sorted(runs):
        r = runs[k]
        rows.append(list(k[:4]) + [k[4], r["status"], r["ate"], r["it"], r["opt_ms"]])
        if k[4] == "marglab":
            b = runs.get(k[:4] + ("basalt",), {"status": "missing"})
            lines.append(f"| {k[0]} | {k[1]} | {k[2]} | {k[3]} | {run_text(r, 'ate', 4)} | "
                         f"{run_text(b, 'ate', 4)} | {run_text(r, 'it', 2)} | "
                         f"{run_text(b, 'it', 2)} |")
    write_csv(os.path.join(out_dir, "stop_rule.csv"), rows)
    write_text(os.path.join(out_dir, "stop_rule.md"), "\n".join(lines) + "\n")
    print(os.path.join(out_dir, "stop_rule.md"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
