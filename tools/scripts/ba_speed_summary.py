#!/usr/bin/env python3
"""Medians and spread of the `marglab ba` speed sweep (experiments/bal_speed.toml) over its rounds.

Usage: ba_speed_summary.py SWEEP_DIR [--tau 0.01]      (markdown on stdout)

The sweep's groups are named r<round>_t<threads>: the same runs repeated in rounds, at 1 and at N
threads. Per problem, best is the lowest final cost any run of any round reached and the threshold
best + tau (initial - best) (rootba's performance profile; `marglab tables` does the same per
group); a run's time to tau is the time of its first iteration at or below it: wall time
(/iterations/time_s) and the process's CPU time (cpu_s, all threads; on a machine shared with other
work the wall time of one thread is inflated by the load, its CPU time much less). Tables:
  1. time to tau per solver, median (min-max) over the rounds, per thread count, wall and CPU;
  2. the fastest Ceres solver's time over ns-f32's, per round (same round and thread count), median
     (min-max), wall and CPU: issue #39's target is >= 2 on every problem;
  3. each solver's scaling: its median time at 1 thread over its median time at N threads;
  4. peak resident memory per solver (median over the rounds; the process, problem included).
Needs numpy, h5py.
"""
import argparse
import csv
import math
import os
import re
import statistics
import sys

import h5py
import numpy as np

CERES = ("ceres-implicit", "ceres-explicit", "ceres-sparse")


def load(sweep):
    runs = []
    with open(os.path.join(sweep, "index.csv"), newline="") as f:
        for row in csv.DictReader(f):
            m = re.fullmatch(r"r(\d+)_t(\d+)", row["group"])
            if not m or row["status"] != "ok":
                continue
            with h5py.File(os.path.join(sweep, row["results"]), "r") as h:
                run = {"round": int(m.group(1)), "threads": int(m.group(2)),
                       "problem": h.attrs["problem"], "solver": row["variant"],
                       "initial": float(h.attrs["initial_cost"]),
                       "final": float(h.attrs["final_cost"]),
                       "peak_mb": float(h.attrs["peak_rss_mb"]),
                       "isa": h.attrs.get("isa", ""),
                       "cost": np.asarray(h["iterations/cost"][()]),
                       "time": np.asarray(h["iterations/time_s"][()]),
                       "cpu": np.asarray(h["iterations/cpu_s"][()])}
            runs.append(run)
    return runs


def time_to(run, threshold, clock):
    hit = np.nonzero(run["cost"] <= threshold)[0]
    return float(run[clock][hit[0]]) if hit.size else math.nan


def spread(values):
    v = [x for x in values if not math.isnan(x)]
    if not v:
        return "—"
    missed = len(values) - len(v)
    text = f"{statistics.median(v):.3g} ({min(v):.3g}–{max(v):.3g})"
    return text + (f" x{missed}/{len(values)}" if missed else "")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("sweep")
    parser.add_argument("--tau", type=float, default=0.01)
    args = parser.parse_args()
    runs = load(args.sweep)
    if not runs:
        sys.exit(f"{args.sweep}: no runs of groups r<round>_t<threads>")
    problems = sorted({r["problem"] for r in runs})
    solvers = [s for s in ("ns-f32", "ns-f64", "nsx-f32", "nsx-f64", "sc-f32", "sc-f64", *CERES)
               if any(r["solver"] == s for r in runs)]
    threads = sorted({r["threads"] for r in runs})
    rounds = sorted({r["round"] for r in runs})
    for p in problems:
        mine = [r for r in runs if r["problem"] == p]
        best = min(r["final"] for r in mine)
        initial = statistics.median(r["initial"] for r in mine)
        for r in mine:
            for clock in ("time", "cpu"):
                r["tau_" + clock] = time_to(r, best + args.tau * (initial - best), clock)
    print_tables(runs, args.tau, problems, solvers, threads, rounds)


def print_tables(runs, tau, problems, solvers, threads, rounds):
    def times(p, s, t, clock="time"):
        return [r["tau_" + clock] for r in runs
                if r["problem"] == p and r["solver"] == s and r["threads"] == t]

    isas = sorted({r["isa"] for r in runs if r["solver"].startswith(("ns", "sc"))})
    print(f"Rounds {rounds}, threads {threads}, kernels of ns / sc: {', '.join(isas)}.\n")
    for clock, what in (("time", "wall"), ("cpu", "CPU")):
        print(f"### Time to τ = {tau} [s, {what}], median (min–max) over the rounds\n")
        print("| problem | threads | " + " | ".join(solvers) + " |")
        print("|---|---:|" + "---:|" * len(solvers))
        for p in problems:
            for t in threads:
                cells = (spread(times(p, s, t, clock)) for s in solvers)
                print(f"| {p} | {t} | " + " | ".join(cells) + " |")
        print()
    for clock, what in (("time", "wall"), ("cpu", "CPU")):
        print(f"### Fastest Ceres solver's time to τ over ns-f32's ({what}), per round: "
              "median (min–max)\n")
        print("| problem | " + " | ".join(f"{t} thread{'s' if t > 1 else ''}" for t in threads)
              + " |")
        print("|---|" + "---:|" * len(threads))
        for p in problems:
            cells = [spread([speedup(runs, p, t, k, clock) for k in rounds]) for t in threads]
            print(f"| {p} | " + " | ".join(cells) + " |")
        print()
    if len(threads) > 1:
        t_hi = threads[-1]
        print(f"### Scaling: median wall time to τ at 1 thread / at {t_hi} threads\n")
        print("| problem | " + " | ".join(solvers) + " |")
        print("|---|" + "---:|" * len(solvers))
        for p in problems:
            cells = []
            for s in solvers:
                one = [x for x in times(p, s, 1) if not math.isnan(x)]
                many = [x for x in times(p, s, t_hi) if not math.isnan(x)]
                cells.append(f"{statistics.median(one) / statistics.median(many):.2f}"
                             if one and many else "—")
            print(f"| {p} | " + " | ".join(cells) + " |")
    print("\n### Peak memory [MB], median over the rounds\n")
    print("| problem | threads | " + " | ".join(solvers) + " |")
    print("|---|---:|" + "---:|" * len(solvers))
    for p in problems:
        for t in threads:
            cells = []
            for s in solvers:
                v = [r["peak_mb"] for r in runs
                     if r["problem"] == p and r["solver"] == s and r["threads"] == t]
                cells.append(f"{statistics.median(v):.1f}" if v else "—")
            print(f"| {p} | {t} | " + " | ".join(cells) + " |")


def speedup(runs, problem, threads, round_, clock):
    def one(solver):
        v = [r["tau_" + clock] for r in runs if r["problem"] == problem and r["solver"] == solver
             and r["threads"] == threads and r["round"] == round_]
        return v[0] if v else math.nan
    return min(one(s) for s in CERES) / one("ns-f32")


if __name__ == "__main__":
    main()
