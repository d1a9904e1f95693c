#!/usr/bin/env python3
"""tools/scripts/nfr_length_table.py's premise and its ATE (issue #19 section 3; used by
test/cli/test_analysis.cpp): a SHORT run (N frames) is bit for bit the first N frames of a LONG run
of the same dataset, variant, seed and config, and the table's prefix ATE reproduces the C++ ATE
of /summary — of the short run from the long run's first N frames, and of the long run whole.

Usage: nfr_length_agrees.py LONG.h5 SHORT.h5   → "AGREE …", exit 0; else what differs and exit 1.
"""
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(HERE)), "tools", "scripts"))
import marglab_results as mr  # noqa: E402
import nfr_length_table as nl  # noqa: E402


def main(long_path, short_path):
    long_run, short_run = mr.read_run(long_path), mr.read_run(short_path)
    n, n_long = len(short_run.frames["t_ns"]), len(long_run.frames["t_ns"])
    problems = []
    if n >= n_long:
        problems.append("SHORT has %d frames, LONG %d" % (n, n_long))
    for name in ("p_est", "p_gt"):
        a, b = short_run.positions(name), long_run.positions(name)[:n]
        if a.shape != b.shape or a.tobytes() != b.tobytes():
            problems.append("%s of SHORT differs from the first %d frames of LONG" % (name, n))
    for what, ate, ref in (("prefix", nl.prefix_ate(long_run, n), short_run.summary["ate_rmse"]),
                           ("whole", nl.prefix_ate(long_run, n_long),
                            long_run.summary["ate_rmse"])):
        if not math.isclose(ate, float(ref), rel_tol=1e-12):
            problems.append("%s ATE %.17g, /summary %.17g" % (what, ate, float(ref)))
    if not np.isfinite(nl.prefix_ate(long_run, n)):
        problems.append("prefix ATE is not finite")
    print("\n".join(problems) if problems else
          "AGREE %d of %d frames, %d sparsify events in the prefix"
          % (n, n_long, len(short_run.sparsify["frame_index"])))
    return 1 if problems else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1], sys.argv[2]))
