#!/usr/bin/env python3
"""Figure of the mass-spring experiment (Levine's marginalization primer, Fig. 3).

Usage: plot_massspring.py STATE.json OUT_PREFIX
Writes OUT_PREFIX.png and OUT_PREFIX.pdf: the initial and the final state side by side. Springs
are drawn with a width that grows with their potential energy (nonlinear p = 4 springs dashed),
masses are coloured by the total energy of the springs attached to them, masses of the nonlinear
set N are outlined, anchors are crosses joined to their corner. STATE.json is written by
`marglab massspring` (needs only matplotlib and numpy).
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import atomic_save  # noqa: E402


def draw(ax, state, x, energies, title, e_max, cmap):
    x = np.asarray(x).reshape(-1, 2)
    springs = np.asarray(state["springs"]).reshape(-1, 3)
    n_springs = len(springs)
    e_spring = np.asarray(energies[:n_springs])
    e_anchor = np.asarray(energies[n_springs:])
    widths = 0.5 + 4.5 * np.sqrt(e_spring / e_max) if e_max > 0 else np.full(n_springs, 1.0)
    segments = [[x[i], x[j]] for i, j, _ in springs]
    styles = ["--" if p == 4 else "-" for _, _, p in springs]
    ax.add_collection(LineCollection(segments, linewidths=widths, colors="0.35", linestyles=styles,
                                     zorder=1))
    anchors = np.asarray(state["anchors"]).reshape(-1, 2)
    for a, m in zip(anchors, state["anchor_mass"]):
        ax.plot([a[0], x[m][0]], [a[1], x[m][1]], ":", color="tab:red", lw=1, zorder=1)
    ax.plot(anchors[:, 0], anchors[:, 1], "x", color="tab:red", ms=8, label="anchor")
    vertex_energy = np.zeros(len(x))
    for (i, j, _), e in zip(springs, e_spring):
        vertex_energy[i] += e
        vertex_energy[j] += e
    for m, e in zip(state["anchor_mass"], e_anchor):
        vertex_energy[m] += e
    nonlinear = np.asarray(state["nonlinear"], dtype=bool)
    sc = ax.scatter(x[:, 0], x[:, 1], c=vertex_energy, cmap=cmap, vmin=0,
                    vmax=max(vertex_energy.max(), 1e-12), s=60, zorder=2,
                    edgecolors=np.where(nonlinear, "k", "none"), linewidths=1.5)
    ax.set_title(f"{title}: energy {np.sum(energies):.4g}")
    ax.set_aspect("equal")
    ax.autoscale_view()
    return sc


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        state = json.load(f)
    prefix = sys.argv[2]
    os.makedirs(os.path.dirname(prefix) or ".", exist_ok=True)
    n = state["n"]
    e_max = max(max(state["energy_initial"]), max(state["energy_final"]))
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))
    for ax, key, title in ((axes[0], "initial", "initial"), (axes[1], "final", "final")):
        sc = draw(ax, state, state[key], state["energy_" + key], title, e_max, "viridis")
        fig.colorbar(sc, ax=ax, shrink=0.8, label="energy of attached springs")
    fig.suptitle(f"Mass-spring grid {n}x{n}: dashed = nonlinear springs (p = 4), "
                 "outlined = masses kept in stage 1")
    fig.tight_layout()
    atomic_save.savefig(fig, prefix + ".png", dpi=150)
    atomic_save.savefig(fig, prefix + ".pdf")


if __name__ == "__main__":
    main()
