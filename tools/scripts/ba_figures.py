"""Figures of `marglab ba` runs in sweep folders (issue #39, docs/bundle_adjustment.md), drawn by
`marglab plot --figure ba_convergence,ba_profile` through plot_paper.py:

  ba_convergence_<group>_<problem>  cost − best against time (log-log), one line per solver for
                                    the sweep's first seed of the problem (rootba's 38401 when it
                                    ran), a cross on each rejected or failed trial; best = the
                                    lowest final cost of any solver on that problem and seed
  ba_profile_<group>                rootba's performance profile for τ ∈ {0.1, 0.01, 0.001}: over
                                    every problem and seed of the group, the fraction a solver
                                    brings to best + τ (initial − best) within α times the fastest
                                    solver's time

The thresholds and times are those of `marglab tables` (core/experiment/ba_tables.h: time of the
first iteration at or below the threshold). Only runs whose results file is in the folder are
drawn.
"""
import collections
import math
import os

import h5py

import marglab_results as mr

TAUS = (0.1, 0.01, 0.001)
SOLVERS = ("ns-f32", "ns-f64", "nsx-f32", "nsx-f64", "sc-f32", "sc-f64", "ceres-implicit",
           "ceres-explicit", "ceres-sparse")
STYLE = {
    "ns-f32": dict(color="tab:green", ls="-", lw=1.6),
    "ns-f64": dict(color="tab:blue", ls="-", lw=1.3),
    "nsx-f32": dict(color="tab:olive", ls=(0, (5, 1)), lw=1.3),
    "nsx-f64": dict(color="tab:cyan", ls=(0, (5, 1)), lw=1.2),
    "sc-f32": dict(color="tab:red", ls="--", lw=1.4),
    "sc-f64": dict(color="tab:orange", ls="--", lw=1.2),
    "ceres-implicit": dict(color="0.2", ls=":", lw=1.3),
    "ceres-explicit": dict(color="0.45", ls="-.", lw=1.3),
    "ceres-sparse": dict(color="tab:purple", ls=":", lw=1.3),
}


def read_ba_runs(rows):
    """The finished ba runs (index column kind = "ba") whose results file is there."""
    runs = []
    for row in rows:
        if row.get("kind") != "ba" or row.get("status") not in ("ok", "failed"):
            continue
        if not row["path"] or not os.path.isfile(row["path"]):
            continue
        with h5py.File(row["path"], "r") as f:
            it = f["iterations"]
            runs.append({
                "group": row["group"], "problem": mr.decode(f.attrs["problem"]),
                "solver": row["variant"], "seed": int(row["seed"]),
                "initial": float(f.attrs["initial_cost"]), "final": float(f.attrs["final_cost"]),
                "cost": list(it["cost"][:]), "t": list(it["time_s"][:]),
                "accepted": list(it["accepted"][:]),
            })
    return runs


def time_to(run, threshold):
    for cost, t in zip(run["cost"], run["t"]):
        if cost <= threshold:
            return t
    return math.inf


def instances(runs):
    """(group, problem, seed) → the runs of that start, by solver."""
    out = collections.defaultdict(dict)
    for r in runs:
        out[(r["group"], r["problem"], r["seed"])][r["solver"]] = r
    return out


def order(solvers):
    return sorted(solvers, key=lambda s: SOLVERS.index(s) if s in SOLVERS else len(SOLVERS))


def plot_convergence(plt, runs, out, save, written):
    starts = instances(runs)
    first_seed = {}
    for (group, problem, seed) in starts:
        key = (group, problem)
        if key not in first_seed or (seed == 38401) or (first_seed[key] != 38401 and seed < first_seed[key]):
            first_seed[key] = seed
    for (group, problem), seed in sorted(first_seed.items()):
        by_solver = starts[(group, problem, seed)]
        best = min(r["final"] for r in by_solver.values())
        fig, ax = plt.subplots(figsize=(6.5, 4.2))
        for solver in order(by_solver):
            r = by_solver[solver]
            gap = [max(c - best, 1e-12 * best) for c in r["cost"]]
            t = [max(x, 1e-4) for x in r["t"]]
            line, = ax.plot(t, gap, label=solver, **STYLE.get(solver, {}))
            bad = [(x, g) for x, g, a in zip(t, gap, r["accepted"]) if not a]
            if bad:
                ax.plot(*zip(*bad), "x", color=line.get_color(), ms=4)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("cost − best")
        ax.set_title("%s, %s, seed %d" % (problem, group, seed), fontsize=9)
        ax.legend(fontsize=7)
        fig.tight_layout()
        save(fig, out, "ba_convergence_%s_%s" % (group, problem), written)


def plot_profile(plt, runs, out, save, written):
    starts = instances(runs)
    for group in sorted({g for (g, _, _) in starts}):
        mine = {k: v for k, v in starts.items() if k[0] == group}
        solvers = order({s for v in mine.values() for s in v})
        fig, axes = plt.subplots(1, len(TAUS), figsize=(4 * len(TAUS), 3.6), sharey=True)
        alphas = [1 + 0.05 * i for i in range(101)]
        for ax, tau in zip(axes, TAUS):
            ratios = collections.defaultdict(list)
            for by_solver in mine.values():
                best = min(r["final"] for r in by_solver.values())
                times = {s: time_to(r, best + tau * (r["initial"] - best))
                         for s, r in by_solver.items()}
                fastest = min(times.values())
                for s in solvers:
                    ratios[s].append(times.get(s, math.inf) / fastest)
            for s in solvers:
                ax.plot(alphas, [sum(x <= a for x in ratios[s]) / len(ratios[s]) for a in alphas],
                        label=s, **STYLE.get(s, {}))
            ax.set_title("τ = %g" % tau)
            ax.set_xlabel("α (time relative to the fastest)")
            ax.set_ylim(-0.02, 1.02)
        axes[0].set_ylabel("fraction of problems × seeds")
        axes[-1].legend(fontsize=7)
        fig.suptitle("%s: performance profile over %d problem × seed starts" % (group, len(mine)),
                     fontsize=10)
        fig.tight_layout()
        save(fig, out, "ba_profile_%s" % group, written)


def plot(plt, rows, figures, out, save, written):
    """The ba figures of `figures` from the index rows; says why one is skipped."""
    wanted = figures & {"ba_convergence", "ba_profile"}
    if not wanted:
        return
    runs = read_ba_runs(rows)
    if not runs:
        print("skipped %s: no ba runs with their results files" % ", ".join(sorted(wanted)))
        return
    if "ba_convergence" in wanted:
        plot_convergence(plt, runs, out, save, written)
    if "ba_profile" in wanted:
        plot_profile(plt, runs, out, save, written)
