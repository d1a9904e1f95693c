#!/usr/bin/env python3
"""The table scripts' shared conventions (tools/scripts/table_common.py; used by
test/cli/test_analysis.cpp):
- a published "mean ± std" uses the sample std (n − 1), as `marglab tables` does (sampleStdOf,
  core/experiment/table_run_stats.cpp), with no spread for a single value, and "x k/n" for k
  failed runs of n — in table_common.seed_cell and in the per-sequence cells of
  nfr_topology_table.py;
- table_common.ate_rmse is the ATE of core/diagnostics/ate.h: zero on an exactly rotated and
  shifted copy, the reflection fix on a planar set, non-finite rows skipped, and equal to the
  independent checker's value (check_results.py, which the tables must not import);
- a failed write leaves the previous file and no temporary behind.

Usage: table_scripts_agree.py SCRATCH_DIR   → "AGREE", exit 0; else what differs and exit 1.
"""
import math
import os
import sys

import numpy as np
from scipy.spatial.transform import Rotation

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(HERE)), "tools", "scripts"))
import check_results  # noqa: E402
import nfr_topology_table as nt  # noqa: E402
import table_common as tc  # noqa: E402


def cell_problems():
    problems = []
    for args, want in ((([1.0, 2.0, 3.0], 0, 3, 4), "2.0000 ± 1.0000 (3)"),  # pstdev: 0.8165
                       (([1.0, 3.0], 1, 3, 1), "2.0 ± 1.4 (2) x 1/3"),
                       (([0.5], 0, 1, 2), "0.50 (1)"),
                       (([], 3, 3, 4), "x 3/3"),
                       (([], 0, 0, 4), "–")):
        got = tc.seed_cell(*args)
        if got != want:
            problems.append("seed_cell%r = %r, expected %r" % (args, got, want))
    runs = {("discard", "MH_03", s): {"ate": a, "status": "ok"}
            for s, a in ((1, 1.0), (2, 2.0), (3, 3.0))}
    runs[("discard", "MH_03", 4)] = {"ate": float("nan"), "status": "failed"}
    got = nt.per_sequence_lines(runs, ["discard"])[-1]
    if got != "| MH_03 | 2.0000 ± 1.0000 (3) x 1/4 |":
        problems.append("nfr_topology per-sequence row %r" % got)
    return problems


def alignment_problems():
    rng = np.random.default_rng(3)
    p_est = np.cumsum(rng.normal(size=(200, 3)), axis=0)
    rot = Rotation.from_euler("zyx", [40.0, -15.0, 8.0], degrees=True)
    p_gt = rot.apply(p_est) + np.array([2.0, -1.0, 0.5])
    problems = []
    if not tc.ate_rmse(p_est, p_gt) < 1e-12:
        problems.append("ATE of a rigidly moved copy: %r" % tc.ate_rmse(p_est, p_gt))
    noisy = p_gt + rng.normal(scale=0.1, size=p_gt.shape)
    noisy[[5, 17]] = np.nan
    ours = tc.ate_rmse(p_est, noisy)
    ok = np.all(np.isfinite(noisy), axis=1)
    theirs = check_results.umeyama_rmse(p_est[ok], noisy[ok])[0]
    if not math.isclose(ours, theirs, rel_tol=1e-12):
        problems.append("ATE %.17g, the checker's %.17g" % (ours, theirs))
    planar = p_est * np.array([1.0, 1.0, 0.0])  # a mirror fits it as well as a rotation
    r, _ = tc.align_rigid(planar, rot.apply(planar))
    if not math.isclose(np.linalg.det(r), 1.0, rel_tol=1e-12):
        problems.append("alignment of a planar set has det %r" % np.linalg.det(r))
    if not math.isnan(tc.ate_rmse(np.full((3, 3), np.nan), p_gt[:3])):
        problems.append("ATE without pairs is not NaN")
    return problems


def atomic_problems(scratch):
    path = os.path.join(scratch, "table.csv")
    tc.write_csv(path, [["a", "b"], [1, 2.5]])
    with open(path, newline="") as f:
        if f.read() != "a,b\r\n1,2.5\r\n":
            return ["write_csv wrote something else than csv.writer"]
    try:
        tc.write_text(path, None)  # fails inside the write
        return ["write_text(None) did not fail"]
    except TypeError:
        pass
    with open(path, newline="") as f:
        kept = f.read() == "a,b\r\n1,2.5\r\n"
    left = [n for n in os.listdir(scratch) if n != "table.csv"]
    return ([] if kept else ["a failed write changed the previous file"]) + \
        (["temporaries left: %r" % left] if left else [])


def main(scratch):
    os.makedirs(scratch, exist_ok=True)
    problems = cell_problems() + alignment_problems() + atomic_problems(scratch)
    for p in problems:
        print(p)
    if problems:
        return 1
    print("AGREE")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
