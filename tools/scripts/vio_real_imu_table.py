#!/usr/bin/python3
"""Issue #40 §1: Table 1's √VIO-64 magnitudes, ours against the paper's, per cell of the real-IMU
study and beside today's tables.

Reads the table1.csv that `marglab tables` wrote for each cell (NAME=FOLDER: the tables folder of
that cell's seed folders) and prints, per sequence, our ATE (mean over the seeds that finished, and
the failures), the paper's, and paper / ours; then per family (EuRoC, TUM-VI rooms) the median of
paper / ours over the sequences the cell has. Writes Markdown to --out.

With --compare LABEL A=FOLDERS B=FOLDERS (repeatable; FOLDERS: one cell's seed folders,
comma-separated, e.g. the synthetic IMU sampled at the start and at the midpoint of its hold) it
adds a table per sequence: both cells' ATEs beside the paper's, B / A on every seed both finished,
and whether B's mean lies closer to the paper's ATE (|log paper / ours| smaller); per family the
medians of paper / ours with their range, and how many sequences moved toward the paper. A run on
a copied folder named <name>_imu<D>ms (tumvi_rooms.py shift-imu) counts for its sequence; the
copies with D = 0 are controls and left out.

  tools/scripts/vio_real_imu_table.py --out results/vio_real_imu/summary.md \
      "ideal, synthetic IMU, Kalibr (today)=results/paper_seeds_tables" \
      "ideal, real IMU=results/vio_real_imu/tables/real_ideal" ... \
      --compare "ideal profile" start=R/synthetic_ideal_s1,... midpoint=R/synthetic_ideal_midpoint_s1,...
"""

import argparse
import csv
import math
import os
import re
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from atomic_save import atomic_path  # noqa: E402

VARIANT = "ns-qr-sqrt-f64"
FAMILIES = {"EuRoC": "euroc/", "TUM-VI rooms": "tumvi/room"}


def read_cell(folder):
    """{sequence: (mean ATE or None, failed, runs, paper ATE)} of the √VIO-64 column."""
    path = os.path.join(folder, "table1.csv")
    try:
        rows = list(csv.DictReader(open(path, encoding="utf-8")))
    except OSError as e:
        sys.exit(f"vio_real_imu_table.py: {path}: cannot read ({e.strerror})")
    out = {}
    for r in rows:
        if r["variant"] != VARIANT or r["ours_state"] not in ("ok", "failed"):
            continue  # missing, or pending in an unfinished folder
        ours = float(r["ours"]) if r["ours"] else None
        runs = int(r["n_runs"])
        # a single run's cell has no failure count: its state says whether it failed
        failed = int(r["ours_failed"]) if r["ours_failed"] else int(r["ours_state"] == "failed")
        out[r["row"]] = (ours, failed if ours is not None else max(failed, 1), runs,
                         float(r["paper"]))
    if not out:
        sys.exit(f"vio_real_imu_table.py: {path}: no {VARIANT} runs")
    return out


def cell_text(value):
    if value is None:
        return "–"
    ours, failed, runs, paper = value
    fail = f" (x {failed}/{runs})" if failed else ""
    if ours is None:
        return f"x {failed}/{runs}"
    return f"{ours:.4f}{fail} · {paper / ours:.2f}"


def medians(cell):
    out = {}
    for family, prefix in FAMILIES.items():
        ratios = [v[3] / v[0] for k, v in cell.items() if k.startswith(prefix) and v[0]]
        out[family] = (statistics.median(ratios), len(ratios)) if ratios else None
    return out


def markdown(names, cells):
    sequences = sorted({k for c in cells for k in c if k.startswith(tuple(FAMILIES.values()))})
    paper = {k: next(c[k][3] for c in cells if k in c) for k in sequences}
    lines = ["| sequence | paper | " + " | ".join(names) + " |",
             "|---|---:|" + "---:|" * len(names)]
    for k in sequences:
        lines.append(f"| {k} | {paper[k]:.3f} | "
                     + " | ".join(cell_text(c.get(k)) for c in cells) + " |")
    for family in FAMILIES:
        meds = [medians(c)[family] for c in cells]
        lines.append(f"| **median paper / ours, {family}** | | " + " | ".join(
            "–" if m is None else f"**{m[0]:.2f}** ({m[1]})" for m in meds) + " |")
    return "\n".join(lines) + "\n"


def sequence_of(dataset):
    """The shipped sequence a run's dataset stands for (None: a control copy, left out)."""
    m = re.fullmatch(r"(?:.*/)?(euroc|tumvi)/(\w+?)(?:_imu(-?[\d.]+)ms)?", dataset)
    if not m:
        return dataset
    if m.group(3) is not None and float(m.group(3)) == 0:
        return None
    return f"{m.group(1)}/{m.group(2)}"


def read_seed_runs(folders):
    """{sequence: {seed: ATE or None (failed)}} of the √VIO-64 runs in the sweep folders' index."""
    out = {}
    for folder in folders:
        path = os.path.join(folder, "index.csv")
        try:
            rows = list(csv.DictReader(open(path, encoding="utf-8")))
        except OSError as e:
            sys.exit(f"vio_real_imu_table.py: {path}: cannot read ({e.strerror})")
        for r in rows:
            sequence = sequence_of(r["dataset"])
            if r["variant"] != VARIANT or r["status"] not in ("ok", "failed") or not sequence:
                continue  # pending or crashed: not a result
            ate = float(r["ate_rmse"]) if r["status"] == "ok" else None
            out.setdefault(sequence, {})[int(r["seed"])] = ate
    if not out:
        sys.exit(f"vio_real_imu_table.py: {', '.join(folders)}: no {VARIANT} runs")
    return out


def mean_text(runs):
    ok = [a for a in runs.values() if a is not None]
    failed = len(runs) - len(ok)
    if not ok:
        return None, f"x {failed}/{len(runs)}"
    fail = f" (x {failed}/{len(runs)})" if failed else ""
    return statistics.fmean(ok), f"{statistics.fmean(ok):.4f}{fail}"


def compare_markdown(names, a_runs, b_runs, paper):
    """Per sequence: A's and B's ATE, paper / ours, B / A per seed, B closer to the paper?"""
    a_name, b_name = names
    lines = [f"| sequence | paper | {a_name}: ATE · paper / ours | {b_name}: ATE · paper / ours "
             f"| {b_name} / {a_name}, per seed | closer to the paper |",
             "|---|---:|---:|---:|---:|:---:|"]
    moved = {f: [] for f in FAMILIES}
    ratios = {f: ([], []) for f in FAMILIES}
    shared = set(a_runs) & set(b_runs) & set(paper)
    for k in sorted(k for k in shared if k.startswith(tuple(FAMILIES.values()))):
        (a, a_text), (b, b_text) = mean_text(a_runs[k]), mean_text(b_runs[k])
        seeds = sorted(s for s in set(a_runs[k]) & set(b_runs[k])
                       if a_runs[k][s] is not None and b_runs[k][s] is not None)
        per_seed = ", ".join(f"{b_runs[k][s] / a_runs[k][s]:.2f}" for s in seeds) or "–"
        closer = "–"
        family = next(f for f, p in FAMILIES.items() if k.startswith(p))
        if a is not None and b is not None:
            toward = abs(math.log(paper[k] / b)) < abs(math.log(paper[k] / a))
            closer = "yes" if toward else "no"
            moved[family].append(toward)
            ratios[family][0].append(paper[k] / a)
            ratios[family][1].append(paper[k] / b)
        a_cell = a_text + (f" · {paper[k] / a:.2f}" if a else "")
        b_cell = b_text + (f" · {paper[k] / b:.2f}" if b else "")
        lines.append(f"| {k} | {paper[k]:.3f} | {a_cell} | {b_cell} | {per_seed} | {closer} |")
    for family in FAMILIES:
        ra, rb = ratios[family]
        if not ra:
            continue
        lines.append(f"| **median paper / ours, {family}** (range) | | "
                     f"**{statistics.median(ra):.2f}** ({min(ra):.2f}–{max(ra):.2f}) | "
                     f"**{statistics.median(rb):.2f}** ({min(rb):.2f}–{max(rb):.2f}) | "
                     f"| {sum(moved[family])} of {len(moved[family])} |")
    return "\n".join(lines) + "\n"


def parse_runs(spec):
    name, sep, folders = spec.partition("=")
    if not sep or not name or not folders:
        sys.exit(f"vio_real_imu_table.py: --compare '{spec}': expected NAME=FOLDER,FOLDER,...")
    return name, read_seed_runs(folders.split(","))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cells", nargs="+", metavar="NAME=FOLDER")
    ap.add_argument("--out", required=True)
    ap.add_argument("--compare", nargs=3, action="append", default=[],
                    metavar=("LABEL", "A=FOLDERS", "B=FOLDERS"),
                    help="two cells' seed folders (comma-separated) side by side, per seed")
    args = ap.parse_args()
    names, cells = [], []
    for spec in args.cells:
        name, sep, folder = spec.partition("=")
        if not sep:
            sys.exit(f"vio_real_imu_table.py: '{spec}': expected NAME=FOLDER")
        names.append(name)
        cells.append(read_cell(folder))
    text = ("Table 1, √VIO-64: our ATE [m] (mean over the seeds that finished; x k/n: k of n "
            "failed) · paper / ours, per cell; medians over the sequences each cell has "
            "(their number in parentheses).\n\n" + markdown(names, cells))
    paper = {k: v[3] for c in cells for k, v in c.items()}
    for label, a_spec, b_spec in args.compare:
        (a_name, a_runs), (b_name, b_runs) = parse_runs(a_spec), parse_runs(b_spec)
        text += (f"\n{label}: our ATE (mean over the seeds that finished) · paper / ours; "
                 f"{b_name} / {a_name} on each seed both finished; closer to the paper: "
                 f"|log(paper / ours)| smaller with {b_name}.\n\n"
                 + compare_markdown((a_name, b_name), a_runs, b_runs, paper))
    with atomic_path(args.out) as tmp:
        open(tmp, "w", encoding="utf-8").write(text)
    print(text)


if __name__ == "__main__":
    main()
