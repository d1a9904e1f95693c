#!/usr/bin/env python3
"""Compares `marglab ba` results files: two files, or the *.h5 of two folders paired by name.

Usage: compare_ba_runs.py A B        (files or folders)

A pair is SAME when the outcome (initial_cost, final_cost, status, num_fixed_points) and every
column of /iterations except the wall time time_s, with its messages, are identical (NaN equal to
NaN); otherwise DIFF with the differing fields and, when the iterations line up, the largest
relative difference of the cost over the iterations and of the final cost (how far in the last
bits two ISAs or builds are). Exits 0 when every pair is SAME, 1 otherwise, 2 for usage errors.
Needs numpy, h5py.
"""
import glob
import os
import sys

import h5py
import numpy as np

OUTCOME = ("initial_cost", "final_cost", "status", "num_fixed_points")
COLUMNS = ("iteration", "cost", "lambda", "cg_iterations", "accepted", "ritz_min", "ritz_max")


def read(path):
    with h5py.File(path, "r") as f:
        run = {k: f.attrs[k] for k in OUTCOME}
        g = f["iterations"]
        run.update({k: np.asarray(g[k][()]) for k in COLUMNS})
        run["messages"] = [m.decode() if isinstance(m, bytes) else str(m)
                           for m in g.attrs["messages"]]
    return run


def equal(a, b):
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        return False
    return np.array_equal(a, b, equal_nan=a.dtype.kind == "f")


def compare(a_path, b_path):
    a, b = read(a_path), read(b_path)
    diff = [k for k in (*OUTCOME, *COLUMNS, "messages") if not equal(a[k], b[k])]
    if not diff:
        return "SAME", True
    note = ""
    if a["cost"].shape == b["cost"].shape:
        rel = np.abs(a["cost"] - b["cost"]) / np.abs(b["cost"])
        note = f"  max rel. cost diff {np.nanmax(rel):.2e}"
    final = abs(a["final_cost"] - b["final_cost"]) / abs(b["final_cost"])
    return f"DIFF {','.join(diff)}  final {final:.2e}{note}", False


def pairs(a, b):
    if os.path.isfile(a):
        return [(a, b)]
    names = sorted(os.path.basename(p) for p in glob.glob(os.path.join(a, "*.h5")))
    return [(os.path.join(a, n), os.path.join(b, n)) for n in names]


def main():
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    ok = True
    for a, b in pairs(sys.argv[1], sys.argv[2]):
        if not os.path.exists(b):
            print(f"MISSING {b}")
            ok = False
            continue
        verdict, same = compare(a, b)
        ok &= same
        print(f"{verdict:8s} {os.path.basename(a)}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
