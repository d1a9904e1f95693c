#!/usr/bin/python3
"""Issue #40 §1: VIO-32's (sc-sc-sq-f32) survival in two sweeps side by side, per sequence and
over the paper's survivals and failures, from the table1.csv that `marglab tables` wrote for each
(NAME=TABLES_FOLDER). Markdown to --out.

  tools/scripts/vio32_survival.py --out results/vio32_imu_midpoint/survival.md \\
      start=results/vio32_imu_start/tables midpoint=results/vio32_imu_midpoint/tables
"""

import argparse
import csv
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from atomic_save import atomic_path  # noqa: E402

VARIANT = "sc-sc-sq-f32"


def read_cell(folder):
    """{sequence: (runs that finished, runs, the paper's state)}."""
    path = os.path.join(folder, "table1.csv")
    try:
        rows = list(csv.DictReader(open(path, encoding="utf-8")))
    except OSError as e:
        sys.exit(f"vio32_survival.py: {path}: cannot read ({e.strerror})")
    out = {}
    for r in rows:
        if r["variant"] != VARIANT or r["ours_state"] not in ("ok", "failed"):
            continue
        runs = int(r["n_runs"])
        # a single run's cell has no failure count: its state says whether it failed
        failed = int(r["ours_failed"]) if r["ours_failed"] else int(r["ours_state"] == "failed")
        if not r["ours"]:
            failed = runs  # no run finished
        out[r["row"]] = (runs - failed, runs, r["paper_state"])
    if not out:
        sys.exit(f"vio32_survival.py: {path}: no {VARIANT} runs")
    return out


def markdown(names, cells):
    sequences = sorted(set.intersection(*(set(c) for c in cells)))
    lines = ["| sequence | the paper's VIO-32 | " + " | ".join(f"{n}: finished" for n in names)
             + " |", "|---|:---:|" + "---:|" * len(names)]
    for k in sequences:
        paper = "survives" if cells[0][k][2] == "ok" else "fails"
        lines.append(f"| {k} | {paper} | "
                     + " | ".join(f"{c[k][0]} / {c[k][1]}" for c in cells) + " |")
    for label, state in (("survivals", "ok"), ("failures", "failed")):
        ks = [k for k in sequences if cells[0][k][2] == state]
        lines.append(f"| **on the paper's {len(ks)} {label}** | | " + " | ".join(
            f"**{sum(c[k][0] for k in ks)} / {sum(c[k][1] for k in ks)}**" for c in cells) + " |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cells", nargs="+", metavar="NAME=FOLDER")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    names, cells = [], []
    for spec in args.cells:
        name, sep, folder = spec.partition("=")
        if not sep:
            sys.exit(f"vio32_survival.py: '{spec}': expected NAME=FOLDER")
        names.append(name)
        cells.append(read_cell(folder))
    text = (f"VIO-32 ({VARIANT}): runs that finished / runs, per sequence and over the sequences "
            "where the paper's VIO-32 survives or fails.\n\n" + markdown(names, cells))
    with atomic_path(args.out) as tmp:
        open(tmp, "w", encoding="utf-8").write(text)
    print(text)


if __name__ == "__main__":
    main()
