#!/usr/bin/env python3
"""Bit-for-bit comparison of marglab results files: two files, or every *.h5 of two folders.

Usage: compare_runs.py A B        (files or folders)

For a refactor that is meant to be exact: every numeric dataset of each pair (/frames, /marg with
its eigenvalues and stored priors, /sparsify, /frontend) must be identical, NaN equal to NaN; wall
times (t_*_s) are skipped. Prints one line per pair (SAME | DIFF with the differing datasets |
MISSING) and exits 0 when all pairs are the same, 1 otherwise, 2 for usage errors. Needs numpy, h5py.
"""
import glob
import os
import sys

import h5py
import numpy as np


def datasets(group, prefix=""):
    out = {}
    for name, item in group.items():
        if isinstance(item, h5py.Group):
            out.update(datasets(item, prefix + name + "/"))
        elif not (name.startswith("t_") and name.endswith("_s")):
            out[prefix + name] = item[()]
    return out


def differing(a_path, b_path):
    with h5py.File(a_path, "r") as a, h5py.File(b_path, "r") as b:
        da, db = datasets(a), datasets(b)
        keys = sorted(set(da) | set(db))
        return [k for k in keys if k not in da or k not in db
                or not np.array_equal(np.asarray(da[k]), np.asarray(db[k]),
                                      equal_nan=np.asarray(da[k]).dtype.kind == "f")]


def pairs(a, b):
    if os.path.isfile(a):
        return [(a, b)]
    return [(f, os.path.join(b, os.path.basename(f))) for f in sorted(glob.glob(os.path.join(a, "*.h5")))]


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    bad = 0
    for a_path, b_path in pairs(argv[1], argv[2]):
        name = os.path.basename(a_path)
        if not os.path.exists(b_path):
            print(f"MISSING {b_path}")
            bad += 1
            continue
        diff = differing(a_path, b_path)
        print(f"SAME {name}" if not diff else f"DIFF {name}: {', '.join(diff[:8])}")
        bad += bool(diff)
    print(f"{bad} pair(s) differ")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
