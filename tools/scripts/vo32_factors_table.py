#!/usr/bin/env python3
"""VO-32's failure on KITTI, one factor at a time (experiments/vo32_factors.toml, README "Where we
depart", item 6): per factor and sequence the outcome, the frame where the run broke down and the
keyframes it had made by then, and how many sequences match the paper's fail / finish pattern.

Usage: vo32_factors_table.py SWEEP_DIR [SWEEP_DIR ...]
       (writes FIRST_DIR/tables/vo32_factors.md and vo32_factors.csv)

Per run (the results file): status and failure frame (index.csv); the breakdown frame — the first
frame whose unaligned position error ‖p_est − p_gt‖ exceeds BREAK_M = 10 m, or the failure frame
if the run ended earlier (a criterion-independent moment: the failure criterion decides when a run
is *stopped*, not when its estimate leaves the ground truth); the keyframes made up to that frame
(/frames/is_keyframe). The paper's pattern (Table 2): VO-32 fails ("x") on KITTI 00, 02, 05, 08,
09 and finishes 03, 04, 06, 07, 10. A run "finishes" here when it is ok with ATE below
EXPLODED_M = 100 m (the paper prints 26.12 m for its degraded KITTI 10).

Why not `marglab tables`: its cells reduce one number per run over seeds; the breakdown frame and
keyframe count are read from the /frames of failed runs, and the match count compares a row with
the paper's pattern. Needs numpy and h5py.
"""
import csv
import os
import statistics
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from table_common import write_csv, write_text  # noqa: E402

BREAK_M = 10.0
EXPLODED_M = 100.0
PAPER_FAILS = {"kitti/00", "kitti/02", "kitti/05", "kitti/08", "kitti/09"}
SEQUENCES = ["kitti/00", "kitti/02", "kitti/03", "kitti/04", "kitti/05", "kitti/06", "kitti/07",
             "kitti/08", "kitti/09", "kitti/10"]


def factor_of(row):
    """The row label: the group for the ISA groups, the variant and override otherwise."""
    if row["group"].startswith("isa-"):
        return f"{row['variant']} {row['group']}"
    return f"{row['variant']} {row['override'] or 'default'}"


def breakdown(path, failure_frame):
    """(breakdown frame or None, keyframes up to it or in all, frames processed)."""
    with h5py.File(path, "r") as h5:
        err = np.linalg.norm(h5["frames/p_est"][()] - h5["frames/p_gt"][()], axis=1)
        kf = np.asarray(h5["frames/is_keyframe"][()], dtype=bool)
    over = np.flatnonzero(np.isfinite(err) & (err > BREAK_M))
    frame = int(over[0]) if over.size else None
    if failure_frame is not None and (frame is None or failure_frame < frame):
        frame = failure_frame
    kfs = int(kf[: frame + 1].sum()) if frame is not None else int(kf.sum())
    return frame, kfs, len(err)


def load(sweeps):
    runs = {}
    for sweep in sweeps:
        with open(os.path.join(sweep, "index.csv"), newline="") as f:
            for row in csv.DictReader(f):
                path = os.path.join(sweep, row["results"])
                if row["status"] not in ("ok", "failed") or not os.path.exists(path):
                    continue
                failed = row["status"] == "failed"
                ff = int(row["failure_frame"]) if failed else None
                frame, kfs, n = breakdown(path, ff)
                ate = float(row["ate_rmse"]) if row["ate_rmse"] else float("nan")
                finished = not failed and ate < EXPLODED_M
                runs[(factor_of(row), row["dataset"], int(row["seed"]))] = {
                    "finished": finished, "failed": failed, "ate": ate, "frame": frame,
                    "kfs": kfs, "n": n, "reason": row["reason"]}
    return runs


def cell(run):
    if run is None:
        return "–"
    if run["finished"]:
        return f"{run['ate']:.3g}" + (f" (kf {run['kfs']})" if run["frame"] is None else " b")
    how = "x" if run["failed"] else f"x {run['ate']:.2g} m,"
    return f"{how} {run['frame']} (kf {run['kfs']})"


def rows(runs):
    out = []
    for factor in sorted({k[0] for k in runs}):
        for seed in sorted({k[2] for k in runs if k[0] == factor}):
            sel = {d: runs.get((factor, d, seed)) for d in SEQUENCES}
            have = [d for d in SEQUENCES if sel[d] is not None]
            fails = [d for d in have if not sel[d]["finished"]]
            match = sum((d in PAPER_FAILS) == (d in fails) for d in have)
            frames = [sel[d]["frame"] for d in fails if sel[d]["frame"] is not None]
            kfs = [sel[d]["kfs"] for d in fails if sel[d]["frame"] is not None]
            out.append([factor, seed] + [cell(sel[d]) for d in SEQUENCES] + [
                f"{len(fails)}/{len(have)}", f"{match}/{len(have)}",
                f"{statistics.median(frames):.0f}" if frames else "–",
                f"{statistics.median(kfs):.0f}" if kfs else "–"])
    return out


def main(argv):
    if len(argv) < 2:
        sys.exit(__doc__)
    runs = load(argv[1:])
    header = ["factor", "seed"] + [d.split("/")[1] for d in SEQUENCES] + [
        "fail", "match paper", "median breakdown frame", "median kf at breakdown"]
    table = rows(runs)
    out = os.path.join(argv[1], "tables")
    os.makedirs(out, exist_ok=True)
    write_csv(os.path.join(out, "vo32_factors.csv"), [header] + table)
    paper = ["paper VO-32", ""] + ["x" if d in PAPER_FAILS else "ok" for d in SEQUENCES] + [
        "5/10", "10/10", "", ""]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header),
             "| " + " | ".join(paper) + " |"]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in table]
    notes = [
        "", f"Cells: ATE [m] of a run that finished below {EXPLODED_M:g} m ('b': its unaligned "
        f"position error passed {BREAK_M:g} m on the way); 'x F (kf K)': failed at frame F with K "
        "keyframes made; 'x A m, F': ok but exploded (ATE A), broke down at frame F. Breakdown: "
        f"the first frame with position error > {BREAK_M:g} m or the failure frame, whichever "
        "comes first.", f"Made by tools/scripts/vo32_factors_table.py {' '.join(argv[1:])}"]
    write_text(os.path.join(out, "vo32_factors.md"), "\n".join(lines + notes) + "\n")
    print("\n".join(lines + notes))


if __name__ == "__main__":
    main(sys.argv)
