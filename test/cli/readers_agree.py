#!/usr/bin/env python3
"""The three readers of the results agree on every run of a sweep (issue #20; used by
test/cli/test_analysis.cpp, runnable by hand on any sweep folder):

  - `marglab tables` (core/experiment/tables.cpp, C++ ResultsReader): SWEEP/tables/tables.csv,
    one row per cell with our value printed with 17 significant digits — Tables 1/2 (ATE) and 3/5
    (optimization, marginalization time) exactly, the ablation averages of Tables 4/6 (ATE, times,
    real-time factor over the sequences with all eight variants) to 1e-12 relative;
  - the Python reader (tools/scripts/marglab_results.py): read_sweep and read_run;
  - check_results.py (independent h5py + numpy checker): no problem, and its own recomputation of
    the ATE (Umeyama alignment) agrees with the file's.

Usage: readers_agree.py SWEEP_DIR   → prints one line per run, "AGREE <n> runs", exit 0; else the
disagreements and exit 1.
"""
import contextlib
import io
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(HERE)), "tools", "scripts"))
import check_results  # noqa: E402
import marglab_results as mr  # noqa: E402

# The tables' quantities of one run, by table: (tables.csv table ids, quantity, reader column).
QUANTITIES = [(("table1", "table2"), "ate", "ate_rmse"),
              (("table3", "table5"), "opt", "t_opt_total_s"),
              (("table3", "table5"), "marg", "t_marg_total_s")]


# Tables 4 / 6: the eight square-root-storage variants, averaged over the sequences (EuRoC / KITTI)
# that have all eight; metric rows.
ABLATION = {"table4": "euroc/", "table6": "kitti/"}
EIGHT = ["%s-sqrt-%s" % (m, p) for m in ("ns-qr", "sc-qr", "ns-sc", "sc-sc") for p in ("f64", "f32")]


def close(a, b):
    """Averages computed in C++ and numpy: equal up to the order of the summation."""
    a, b = float(a), float(b)
    return abs(a - b) <= 1e-12 * max(abs(a), abs(b))


def check_ablation(sweep, tables, runs):
    """Table 4 / 6 cells against the reader's values of the runs they average; returns
    (problems, ids of the runs in some cell)."""
    problems, used = [], set()
    for table, prefix in ABLATION.items():
        cells = tables[tables["table"] == table]
        if cells.empty:
            continue
        sub = sweep[sweep["dataset"].str.startswith(prefix) & sweep["variant"].isin(EIGHT) &
                    (sweep["override"].fillna("") == "")]
        sequences = [d for d, g in sub.groupby("dataset") if set(g["variant"]) >= set(EIGHT)]
        for variant in EIGHT:
            rs = sub[sub["dataset"].isin(sequences) & (sub["variant"] == variant)]
            used.update(rs["id"])
            mine = cells[cells["variant"] == variant]
            if (rs["state"] == "failed").any():
                bad = mine[mine["ours_state"] != "failed"]
                problems += ["%s %s %s: a run failed but the cell is %s"
                             % (table, variant, c["quantity"], c["ours_state"])
                             for _, c in bad.iterrows()]
                continue
            s = [runs[i].summary for i in rs["id"]]
            opt = [x["t_opt_total_s"] for x in s]
            marg = [x["t_marg_total_s"] for x in s]
            expected = {
                "ate_m": sum(x["ate_rmse"] for x in s) / len(s),
                "t_opt_s": sum(opt) / len(s), "t_marg_s": sum(marg) / len(s),
                "t_total_s": sum(o + m for o, m in zip(opt, marg)) / len(s),
                "realtime": sum(x["duration_s"] for x in s) / sum(o + m for o, m in zip(opt, marg)),
            }
            for _, c in mine.iterrows():
                want = expected.get(c["quantity"])
                if want is None:
                    continue
                if not close(c["ours"], want):
                    problems.append("%s %s %s: tables %r vs reader %r" % (
                        table, variant, c["quantity"], c["ours"], want))
    return problems, used


def same(a, b):
    """Equal as the tables print them (%.17g round-trips a double exactly)."""
    if a is None or b is None:
        return False
    a, b = float(a), float(b)
    return (math.isnan(a) and math.isnan(b)) or a == b


def main(sweep_dir):
    problems = []
    sweep = mr.read_sweep(sweep_dir)
    tables = mr.read_tables(sweep_dir)
    if tables is None:
        print("%s: no tables/tables.csv (run `marglab tables` first)" % sweep_dir, file=sys.stderr)
        return 1
    tables = tables[tables["override"].fillna("") == ""]
    checked = 0
    runs = {}
    for _, r in sweep.iterrows():
        rid = r["id"]
        if not r["path"] or not os.path.isfile(r["path"]):
            problems.append("%s: no results file" % rid)
            continue
        run = mr.read_run(r["path"])
        runs[rid] = run
        # The reader's run and its sweep summary are the same numbers.
        for name in ("ate_rmse", "t_opt_total_s", "t_marg_total_s", "n_frames"):
            if not same(run.summary.get(name), r[name]):
                problems.append("%s: %s read_run %r vs read_sweep %r"
                                % (rid, name, run.summary.get(name), r[name]))
        if run.status != r["state"]:
            problems.append("%s: status %s vs state %s" % (rid, run.status, r["state"]))
        if len(run.frames) != int(r["n_frames"]):
            problems.append("%s: %d /frames rows vs n_frames %s" % (rid, len(run.frames),
                                                                     r["n_frames"]))
        # check_results.py: no problem, its own ATE equals the reader's.
        with contextlib.redirect_stdout(io.StringIO()):
            found, values = check_results.check_file(r["path"])
        problems += ["%s: check_results: %s" % (rid, p) for p in found]
        ate = run.summary["ate_rmse"]
        if values and not (math.isnan(ate) and math.isnan(values["ate_numpy"])):
            scale = max(float(abs(run.positions("p_gt")).max()), 1e-3) if len(run.frames) else 1
            if not abs(values["ate_numpy"] - ate) <= 1e-9 * scale:
                problems.append("%s: ATE check_results %.12g vs reader %.12g"
                                % (rid, values["ate_numpy"], ate))
        # tables.cpp: every cell of this run (single seed: one run per cell).
        cells = tables[(tables["row"] == r["dataset"]) & (tables["variant"] == r["variant"])]
        for ids, quantity, column in QUANTITIES:
            c = cells[cells["table"].isin(ids) & (cells["quantity"] == quantity)]
            for _, cell in c.iterrows():
                if int(cell["n_runs"]) != 1:
                    continue
                if r["state"] == "failed":
                    if cell["ours_state"] != "failed":
                        problems.append("%s: failed, but %s %s is %s" % (
                            rid, cell["table"], quantity, cell["ours_state"]))
                elif not same(cell["ours"], run.summary[column]):
                    problems.append("%s: %s %s: tables %r vs reader %r" % (
                        rid, cell["table"], quantity, cell["ours"], run.summary[column]))
        checked += 1
        print("%-45s %-6s ATE %-22r check_results %-22r cells %d"
              % (rid, run.status, ate, values.get("ate_numpy") if values else None, len(cells)))
    found, in_ablation = check_ablation(sweep, tables, runs)
    problems += found
    for _, r in sweep.iterrows():
        in_table = ((tables["row"] == r["dataset"]) & (tables["variant"] == r["variant"])).any()
        if r["id"] in runs and not in_table and r["id"] not in in_ablation:
            problems.append("%s: in no table of tables.csv" % r["id"])
    for p in problems:
        print(p, file=sys.stderr)
    if problems:
        return 1
    print("AGREE %d runs" % checked)
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[-2], file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
