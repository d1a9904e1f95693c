#!/usr/bin/env python3
"""tools/scripts/plot_paper.py's Fig. 4 yaw measure (issue #40 §3; used by
test/cli/test_analysis.cpp) on constructed ΔE_m series with known answers: rho is |yaw| over the
smaller of |roll|, |pitch| and absent where roll and pitch are not observable; the onset is where
the running median reaches YAW_ONSET (the rise) and where it stays above it for good (settled) — a
spike is no rise, a rise that falls back does not settle.

Usage: fig4_yaw_agrees.py   → "AGREE …", exit 0; else what differs and exit 1.
"""
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(HERE)), "tools", "scripts"))
import plot_paper as pp  # noqa: E402


class FakeRun:
    def __init__(self, yaw, roll=2e5, pitch=1e5):
        n = len(yaw)
        self.dEm = np.zeros((n, 7))
        self.dEm[:, 3], self.dEm[:, 4], self.dEm[:, 5] = roll, -pitch, yaw  # signs do not matter
        self.marg_frame = np.arange(2, n + 2)


def main():
    problems = []
    n, rise = 3000, 1200
    yaw = np.full(n, 1e-3 * 1e5)
    yaw[rise:] = 0.1 * 1e5
    yaw[500] = 1e5  # a spike: touches the level, is no onset
    frames, rho = pp.yaw_ratio(FakeRun(yaw))
    if not np.allclose(rho[:rise][np.arange(rise) != 500], 1e-3) or not np.allclose(rho[rise:], 0.1):
        problems.append("rho is not |yaw| / min(|roll|, |pitch|)")
    onset, settled = pp.yaw_onset(rho)
    # The running median crosses at the rise: its window is centred there.
    if onset != rise or settled != rise:
        problems.append("rise %s, settled %s, expected event %d" % (onset, settled, rise))
    falls = yaw.copy()
    falls[2500:] = 1e-3 * 1e5
    if pp.yaw_onset(pp.yaw_ratio(FakeRun(falls))[1]) != (rise, None):
        problems.append("a rise that falls back: %s, expected (%d, None)"
                        % (pp.yaw_onset(pp.yaw_ratio(FakeRun(falls))[1]), rise))
    if pp.yaw_onset(pp.yaw_ratio(FakeRun(np.full(n, 1e-3 * 1e5)))[1]) != (None, None):
        problems.append("a flat run has a rise")
    _, early = pp.yaw_ratio(FakeRun(np.full(10, 1.0), roll=0.5))
    if not np.all(np.isnan(early)):
        problems.append("rho where roll is not observable (< YAW_MIN_LEVEL)")
    if problems:
        print("\n".join(problems))
        return 1
    print("AGREE onset at frame %d of %d" % (frames[onset], n))
    return 0


if __name__ == "__main__":
    sys.exit(main())
