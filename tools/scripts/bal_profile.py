#!/usr/bin/env python3
"""Tables of `marglab ba` runs (docs/bundle_adjustment.md): final costs, f32 against f64, time to
rootba's tolerances and peak memory, from a folder of results files (*.h5 with kind = "ba").

Time to τ (rootba's performance profiles): with `best` the lowest final cost any solver reached on
the problem (same start, seed and loss) and `initial` the initial cost, the first time a run's cost
is ≤ best + τ (initial − best); "-" when it never is. Ratio: that time over the fastest solver's.

usage: bal_profile.py FOLDER   (prints Markdown)
"""
import collections
import glob
import math
import sys

import h5py

TAUS = (0.1, 0.01, 0.001)


def load(folder):
    runs = []
    for path in sorted(glob.glob(folder + "/*.h5")):
        with h5py.File(path, "r") as f:
            if f.attrs.get("kind") != "ba":
                continue
            a = dict(f.attrs)
            it = f["iterations"]
            runs.append({
                "problem": a["problem"], "solver": a["solver"],
                "setting": "{} it, huber {:g}, normalize {:g}, perturb {:g} seed {}".format(
                    int(a["iterations"]), a["huber_px"], a["normalize_scale"], a["perturb_sigma"],
                    int(a["seed"])),
                "initial": float(a["initial_cost"]), "final": float(a["final_cost"]),
                "status": a["status"], "time": float(a["total_time_s"]),
                "rss": float(a["peak_rss_mb"]), "cost": list(it["cost"][:]),
                "t": list(it["time_s"][:]), "accepted": list(it["accepted"][:]),
                "iterations": len(it["cost"]) - 1,
            })
    return runs


def time_to(run, threshold):
    for cost, t in zip(run["cost"], run["t"]):
        if cost <= threshold:
            return t
    return math.inf


def main(folder):
    groups = collections.defaultdict(list)
    for r in load(folder):
        groups[(r["problem"], r["setting"])].append(r)
    print("| problem | solver | initial cost | final cost | rel. to f64 | rejected | iterations | time [s] | "
          + " | ".join(f"t(τ={tau}) [s] (×fastest)" for tau in TAUS) + " | peak RSS [MB] |")
    print("|---|---|---:|---:|---:|---:|---:|---:|" + "---:|" * len(TAUS) + "---:|")
    for (problem, setting), runs in sorted(groups.items()):
        best = min(r["final"] for r in runs)
        by_solver = {r["solver"]: r for r in runs}
        fastest = {tau: min(time_to(r, best + tau * (r["initial"] - best)) for r in runs) for tau in TAUS}
        for r in sorted(runs, key=lambda r: r["solver"]):
            twin = by_solver.get(r["solver"].replace("f32", "f64"))
            rel = f"{(r['final'] - twin['final']) / twin['final']:+.1e}" if twin and twin is not r else ""
            cells = []
            for tau in TAUS:
                t = time_to(r, best + tau * (r["initial"] - best))
                cells.append("-" if math.isinf(t) else f"{t:.3f} ({t / fastest[tau]:.1f})")
            rejected = sum(1 for a in r["accepted"][1:] if not a)
            print(f"| {problem} ({setting}) | {r['solver']} | {r['initial']:.6e} | {r['final']:.6e} | {rel} | "
                  f"{rejected} | {r['iterations']} | {r['time']:.3f} | " + " | ".join(cells) + f" | {r['rss']:.0f} |")


if __name__ == "__main__":
    main(sys.argv[1])
