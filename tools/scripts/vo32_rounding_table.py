#!/usr/bin/env python3
"""Where VO-32's f32 Hessian prior loses its rounding race (README "Where we depart", item 6;
experiments/vo32_rate_rounding.toml): per run of a sweep with diagnostics.marg_rounding, from
runs/ID.rounding.csv (core/estimator/marg_rounding.h) and the results file:

- the rounding each stage injects per marginalization event, relative to the marginal (median
  ‖E‖_F / ‖S‖_F over the events: `new` the new factors' system in f32, `add` the old prior added
  in f32, `schur` the poses eliminated in f32 — events that eliminate poses only), and the share of
  the error that lands in the gauge block (Σ |trace Gᵀ E G| over the events, per stage / all);
- the prior's least information along a rigid motion of the window, g = λ_min(Gᵀ S G) (exact: the
  double reference of each event), against σ_max: g / σ_max at events 25, 100, 200, and the
  first frames where it falls below ε_f32 (1.2e-7: one f32 rounding of a matrix of norm σ_max)
  and ε_f32 / 10;
- the breakdown frame (vo32_factors_table.py: first frame with position error > 10 m, or the
  failure frame) and the first frame where the run's f32 prior is indefinite along a rigid motion
  (g_run < 0); the accumulated f32 error in that block, median |g_run − g_ref| / σ_max over the
  events; and whether the least-informed rigid motion is a translation (median over the events
  after 100 of the least information along a translation / g, 1: a translation).

Usage: vo32_rounding_table.py SWEEP_DIR   (writes SWEEP_DIR/tables/vo32_rounding.{md,csv})
Needs numpy and h5py.
"""
import csv
import os
import statistics
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from table_common import write_csv, write_text  # noqa: E402
from vo32_factors_table import breakdown  # noqa: E402

EPS_F32 = float(np.finfo(np.float32).eps)
LEVELS = (EPS_F32, EPS_F32 / 10)


def read_rounding(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]} if rows else None


def first_frame(frames, mask):
    idx = np.flatnonzero(mask)
    return int(frames[idx[0]]) if idx.size else None


def ratio_at(r, event):
    if len(r["frame_index"]) <= event:
        return float("nan")
    return r["gauge_min_ref"][event] / r["sigma_max"][event]


def summarize(sweep, row):
    base = os.path.join(sweep, row["results"])
    r = read_rounding(base[: -len(".h5")] + ".rounding.csv")
    if r is None:
        return None
    failed = row["status"] == "failed"
    frame, _, n = breakdown(base, int(row["failure_frame"]) if failed else None)
    poses = r["n_marg"] > 0
    med = lambda a: float(np.median(a)) if a.size else float("nan")  # noqa: E731
    traces = {s: float(np.sum(np.abs(r[f"{s}_gauge_trace"]))) for s in ("new", "add", "schur")}
    total = sum(traces.values())
    frames = r["frame_index"]
    return [row["group"], row["dataset"].split("/")[1], row["status"],
            frame if frame is not None else f"– ({n})",
            f"{med(r['new_rel']):.1e}", f"{med(r['add_rel']):.1e}",
            f"{med(r['schur_rel'][poses]):.1e}",
            " / ".join(f"{traces[s] / total:.2f}" if total > 0 else "–"
                       for s in ("new", "add", "schur")),
            f"{med(r['sigma_max']):.1e}",
            " / ".join(f"{ratio_at(r, e):.0e}" for e in (25, 100, 200)),
            *[first_frame(frames, r["gauge_min_ref"] < level * r["sigma_max"]) or "–"
              for level in LEVELS],
            first_frame(frames, r["gauge_min_run"] < 0) or "–",
            f"{med(np.abs(r['gauge_min_run'] - r['gauge_min_ref']) / r['sigma_max']):.0e}",
            f"{med(r['translation_min_ref'][frames > 100] / r['gauge_min_ref'][frames > 100]):.2f}"]


def main(argv):
    if len(argv) != 2:
        sys.exit(__doc__)
    sweep = argv[1]
    with open(os.path.join(sweep, "index.csv"), newline="") as f:
        index = [r for r in csv.DictReader(f) if r["status"] in ("ok", "failed")]
    table = [s for s in (summarize(sweep, r) for r in index) if s is not None]
    table.sort(key=lambda t: (t[0], t[1]))
    header = ["group", "seq", "status", "breakdown frame", "new rel", "add rel", "schur rel",
              "gauge-block share new / add / schur", "median σ_max", "g/σ_max at event 25 / 100 / 200",
              *[f"frame g/σ_max < {level:.1e}" for level in LEVELS],
              "frame f32 prior indefinite along a rigid motion", "|g_run − g_ref| / σ_max",
              "translation / g"]
    out = os.path.join(sweep, "tables")
    os.makedirs(out, exist_ok=True)
    write_csv(os.path.join(out, "vo32_rounding.csv"), [header] + table)
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in t) + " |" for t in table]
    for group in sorted({t[0] for t in table}):
        for col, level in zip((10, 11), LEVELS):
            pairs = [(t[3], t[col]) for t in table if t[0] == group
                     and isinstance(t[3], int) and isinstance(t[col], int)]
            if pairs:
                lines.append(f"\n{group}: median breakdown frame "
                             f"{statistics.median(p[0] for p in pairs):.0f}, median frame where "
                             f"g/σ_max < {level:.1e}: {statistics.median(p[1] for p in pairs):.0f}"
                             f" ({len(pairs)} runs with both)")
        crossed = [t[11] for t in table if t[0] == group and isinstance(t[11], int)]
        if crossed and group != "vo32":
            lines.append(f"\n{group}: median frame where g/σ_max < {LEVELS[1]:.1e}: "
                         f"{statistics.median(crossed):.0f} ({len(crossed)} runs)")
    lines.append(f"\nMade by tools/scripts/vo32_rounding_table.py {sweep}")
    write_text(os.path.join(out, "vo32_rounding.md"), "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv)
