#!/usr/bin/python3
"""Profile provenance (ctest profile_provenance): each shipped `realistic` simulator profile is what
tools/scripts/frontend_stats.py computes from the shipped frames today.

For every profile it makes the inputs its calibration used in a scratch folder (the real frames'
tracks, the ideal simulation of the same frames and, where the profile was measured at a run's
frames, the runs on both; the commands of results/frontend_stats/README.md), reruns the
frontend_stats.py command written in the profile's header with the scratch files, and compares every
`key = value` line with the shipped file's, as written (%.6g). Exit 0 when all match, 1 naming the
file and the differing lines.

realistic_euroc.toml (the static V1_01 clip) is not checked: it was calibrated with an earlier
front-end, which tracked those frames differently (results/frontend_stats/README.md), and is kept
as it is because the committed results/realistic were made with it.
"""

import argparse
import os
import re
import shlex
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# Per profile: the marglab commands that make the scratch inputs named in its header command.
INPUTS = {
    "realistic_kitti.toml": [
        "datasets track --dataset kitti/06_images -o real_tracks.h5",
        "run --tracks real_tracks.h5 --dataset kitti/06_images --variant ns-qr-sqrt-f64 "
        "-o real_run.h5",
        "datasets simulate --dataset kitti/06 --seed 1 --frames 51 -o ideal_tracks.h5",
        "run --tracks ideal_tracks.h5 --dataset kitti/06_images --variant ns-qr-sqrt-f64 "
        "-o ideal_run.h5",
    ],
    "realistic_euroc_motion.toml": [
        "datasets track --dataset euroc/V1_01_easy_keyframes -o real_tracks.h5",
        "datasets simulate --dataset euroc/V1_01_easy_keyframes --seed 1 -o ideal_tracks.h5",
    ],
}


def values(text):
    """The profile's `key = value` lines per [section], as written."""
    section, out = "", {}
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if re.fullmatch(r"\[\w+\]", line):
            section = line
        elif "=" in line:
            key, value = (x.strip() for x in line.split("=", 1))
            out[f"{section} {key}"] = value
    return out


def header_command(path):
    """The frontend_stats.py arguments written in the profile's header."""
    for line in open(path, encoding="utf-8"):
        m = re.match(r"#\s+tools/scripts/frontend_stats\.py (.*)$", line)
        if m:
            return shlex.split(m.group(1))
    raise SystemExit(f"{path}: no frontend_stats.py command in the header")


def rerun(name, marglab, scratch):
    """The profile recomputed from the shipped frames in scratch; its text."""
    for command in INPUTS[name]:
        subprocess.run([marglab, *shlex.split(command)], cwd=scratch, check=True,
                       stdout=subprocess.DEVNULL)
    args = header_command(os.path.join(ROOT, "datasets", "sim_profiles", name))
    for i, a in enumerate(args):
        if a.endswith(".h5"):
            args[i] = os.path.join(scratch, a)
        elif args[i - 1] == "--out":
            args[i] = os.path.join(scratch, "out")
        elif args[i - 1] == "--profile-out":
            args[i] = os.path.join(scratch, name)
    subprocess.run([sys.executable, os.path.join(ROOT, "tools", "scripts", "frontend_stats.py"),
                    *args], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    return open(os.path.join(scratch, name), encoding="utf-8").read()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--marglab", required=True, help="the marglab binary to make the inputs with")
    ap.add_argument("profiles", nargs="*", default=sorted(INPUTS), help="profile file names")
    args = ap.parse_args()
    failed = False
    for name in args.profiles:
        if name not in INPUTS:
            raise SystemExit(f"unknown profile {name}: expected one of {sorted(INPUTS)}")
        shipped = values(open(os.path.join(ROOT, "datasets", "sim_profiles", name),
                              encoding="utf-8").read())
        with tempfile.TemporaryDirectory(prefix="profile_provenance_") as scratch:
            computed = values(rerun(name, os.path.abspath(args.marglab), scratch))
        diff = [f"  {k}: shipped {shipped.get(k)}, computed {computed.get(k)}"
                for k in sorted(set(shipped) | set(computed)) if shipped.get(k) != computed.get(k)]
        print(f"datasets/sim_profiles/{name}: " + ("differs\n" + "\n".join(diff) if diff else
                                                    f"{len(shipped)} values match"))
        failed |= bool(diff)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
