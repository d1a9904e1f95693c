#!/usr/bin/env python3
"""Figures of `marglab ba` runs (docs/bundle_adjustment.md), as rootba draws them:

  convergence_<problem>.png   cost − best against time (log), one line per solver, markers on
                              rejected trials; best = the lowest final cost on the problem
  profile.png                 rootba's performance profile for τ ∈ {0.1, 0.01, 0.001}: the fraction
                              of problems a solver brings to best + τ (initial − best) within α
                              times the fastest solver's time

usage: bal_plot.py FOLDER [OUT_FOLDER (FOLDER)]
"""
import collections
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, os.path.dirname(__file__))
from bal_profile import TAUS, load, time_to  # noqa: E402


def convergence(problem, runs, out):
    best = min(r["final"] for r in runs)
    fig, ax = plt.subplots(figsize=(6, 4))
    for r in sorted(runs, key=lambda r: r["solver"]):
        gap = [max(c - best, 1e-12 * best) for c in r["cost"]]
        line, = ax.plot(r["t"], gap, label=r["solver"], lw=1.2)
        rejected = [(t, g) for t, g, a in zip(r["t"], gap, r["accepted"]) if not a]
        if rejected:
            ax.plot(*zip(*rejected), "x", color=line.get_color(), ms=4)
    ax.set_yscale("log")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("cost − best")
    ax.set_title(problem, fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out, f"convergence_{problem}.png"), dpi=120)
    plt.close(fig)


def profile(groups, out):
    fig, axes = plt.subplots(1, len(TAUS), figsize=(4 * len(TAUS), 3.5), sharey=True)
    solvers = sorted({r["solver"] for runs in groups.values() for r in runs})
    alphas = [1 + 0.05 * i for i in range(101)]
    for ax, tau in zip(axes, TAUS):
        ratios = collections.defaultdict(list)
        for runs in groups.values():
            best = min(r["final"] for r in runs)
            times = {r["solver"]: time_to(r, best + tau * (r["initial"] - best)) for r in runs}
            fastest = min(times.values())
            for s in solvers:
                ratios[s].append(times.get(s, math.inf) / fastest)
        for s in solvers:
            ax.plot(alphas, [sum(x <= a for x in ratios[s]) / len(ratios[s]) for a in alphas], label=s)
        ax.set_title(f"τ = {tau}")
        ax.set_xlabel("α (time relative to the fastest)")
    axes[0].set_ylabel("fraction of problems")
    axes[-1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "profile.png"), dpi=120)
    plt.close(fig)


def main(folder, out):
    groups = collections.defaultdict(list)
    for r in load(folder):
        groups[r["problem"]].append(r)
    for problem, runs in groups.items():
        convergence(problem, runs, out)
    profile(groups, out)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else sys.argv[1])
