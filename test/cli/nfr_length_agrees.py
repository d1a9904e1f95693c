#!/usr/bin/env python3
"""tools/scripts/nfr_length_table.py's premise and its ATE (issue #19 section 3; used by
test/cli/test_analysis.cpp): a SHORT run (N frames) is bit for bit the first N frames of a LONG run
of the same dataset, variant, seed and config, and the table's prefix ATE reproduces the C++ ATE
of /summary — of the short run from the long run's first N frames, and of the long run whole.
Also the table's attitude split on a constructed case: an estimate in a rotated and shifted world
frame whose orientations carry a known world-frame error (a pure tilt, then a pure yaw) gives back
that tilt and yaw after the position alignment.

Usage: nfr_length_agrees.py LONG.h5 SHORT.h5   → "AGREE …", exit 0; else what differs and exit 1.
"""
import math
import os
import sys

import numpy as np
from scipy.spatial.transform import Rotation

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(HERE)), "tools", "scripts"))
import marglab_results as mr  # noqa: E402
import nfr_length_table as nl  # noqa: E402


def attitude_problems():
    """nl.attitude_rms on an estimate with a known world-frame attitude error, in another frame."""
    rng = np.random.default_rng(7)
    n = 300
    p_gt = np.cumsum(rng.normal(size=(n, 3)), axis=0)
    r_gt = Rotation.from_rotvec(rng.normal(size=(n, 3)))
    world = Rotation.from_euler("zyx", [30.0, -10.0, 5.0], degrees=True)  # estimate's world frame
    p_est = world.inv().apply(p_gt - np.array([1.0, -2.0, 0.5]))
    problems = []
    for name, error, want in (("tilt", Rotation.from_euler("x", 0.5, degrees=True), (0.5, 0.0)),
                              ("yaw", Rotation.from_euler("z", 0.3, degrees=True), (0.0, 0.3))):
        q_est = (world.inv() * error * r_gt).as_quat()
        got = nl.attitude_rms(p_est, q_est, p_gt, r_gt.as_quat())
        if not np.allclose(got, want, rtol=0, atol=1e-6):
            problems.append("attitude of a pure %s error: %r, expected %r" % (name, got, want))
    return problems


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
    problems += attitude_problems()
    print("\n".join(problems) if problems else
          "AGREE %d of %d frames, %d sparsify events in the prefix"
          % (n, n_long, len(short_run.sparsify["frame_index"])))
    return 1 if problems else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1], sys.argv[2]))
