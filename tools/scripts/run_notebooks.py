#!/usr/bin/env python3
"""Executes marglab's notebooks (notebooks/*.ipynb) headlessly on a sweep folder.

Usage: run_notebooks.py --sweep results/NAME --out notebooks-out/NAME
                        [--notebooks notebooks] [--runs all|none|ID,ID...] [--jobs N] [--timeout S]

Writes, each as the executed .ipynb (with outputs) and as .html (nbconvert's HTML exporter):
  OUT/sweep.{ipynb,html}          notebooks/sweep.ipynb: failure matrix, ATE and runtime tables
                                  beside the paper's, f32 - f64 differences
  OUT/precision.{ipynb,html}      notebooks/precision.ipynb: f32 vs f64 frame by frame
  OUT/runs/<ID>.{ipynb,html}      notebooks/run.ipynb once per run with a results file
  OUT/notebooks.json              what ran, how long, and whether it succeeded (read by the report)
Parameters are given papermill-style: a cell tagged `injected-parameters` is inserted after the
notebook's cell tagged `parameters`. The kernel is the python3 of this interpreter. Exit 0 when
every notebook ran, 1 otherwise (the failing cell's error is printed), 2 for usage errors.
Needs nbformat, nbclient, nbconvert, ipykernel, pandas, h5py, numpy, matplotlib (Debian:
jupyter-nbconvert python3-ipykernel python3-pandas python3-h5py python3-numpy python3-matplotlib).
"""
import argparse
import concurrent.futures
import json
import os
import re
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
DEBIAN = ("jupyter-nbconvert python3-ipykernel python3-pandas python3-h5py python3-numpy "
          "python3-matplotlib")

try:
    import nbformat
    from nbclient import NotebookClient
    from nbclient.exceptions import CellExecutionError
    from nbconvert import HTMLExporter
    import ipykernel  # noqa: F401  (the kernel)
    import pandas  # noqa: F401
    import h5py  # noqa: F401
    import matplotlib  # noqa: F401
except ImportError as e:
    print("run_notebooks.py: %s. Install the Debian packages: sudo apt-get install %s"
          % (e, DEBIAN), file=sys.stderr)
    sys.exit(3)

sys.path.insert(0, HERE)
import atomic_save  # noqa: E402
import marglab_results as mr  # noqa: E402


def inject(nb, params):
    """Inserts the parameters after the cell tagged `parameters` (at the top when none is)."""
    source = "# Parameters injected by `marglab notebooks`\n" + "".join(
        "%s = %r\n" % (k, v) for k, v in params.items())
    cell = nbformat.v4.new_code_cell(source, metadata={"tags": ["injected-parameters"]})
    at = 0
    for i, c in enumerate(nb.cells):
        if "parameters" in c.get("metadata", {}).get("tags", []):
            at = i + 1
            break
    nb.cells.insert(at, cell)


def html_exporter():
    """JupyterLab's HTML without network resources (tools/scripts/nbtemplates/marglab): the
    pages open offline."""
    return HTMLExporter(extra_template_basedirs=[os.path.join(HERE, "nbtemplates")],
                        template_name="marglab")


def execute(task):
    """Runs one notebook; returns its manifest entry. Runs in a worker process."""
    notebook, out_base, params, timeout = task
    start = time.monotonic()
    entry = {"notebook": os.path.basename(notebook), "ipynb": out_base + ".ipynb",
             "html": out_base + ".html", "params": params, "ok": False, "error": ""}
    nb = nbformat.read(notebook, as_version=4)
    inject(nb, params)
    client = NotebookClient(nb, timeout=timeout, kernel_name="python3",
                            resources={"metadata": {"path": os.path.dirname(notebook)}})
    log = open(os.devnull, "w")
    try:
        # The kernel's own stderr (debugger warnings) is noise here; cell errors come back
        # through the protocol and are reported below.
        client.execute(stderr=log)
        entry["ok"] = True
    except CellExecutionError as e:
        entry["error"] = str(e)
    except Exception as e:  # kernel died, timeout: still write what ran
        entry["error"] = "%s: %s" % (type(e).__name__, e)
    finally:
        log.close()
    os.makedirs(os.path.dirname(out_base), exist_ok=True)
    text = nbformat.writes(nb)
    atomic_save.write_text(out_base + ".ipynb", text if text.endswith("\n") else text + "\n")
    body, _ = html_exporter().from_notebook_node(nb)
    atomic_save.write_text(out_base + ".html", body)
    entry["seconds"] = round(time.monotonic() - start, 2)
    return entry


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sweep", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--notebooks", default=os.path.join(os.path.dirname(os.path.dirname(HERE)),
                                                            "notebooks"))
    parser.add_argument("--runs", default="all", help="all | none | comma-separated run ids")
    parser.add_argument("--jobs", type=int, default=0, help="notebooks in parallel (0: cores)")
    parser.add_argument("--timeout", type=int, default=900, help="per cell [s]")
    args = parser.parse_args()

    sweep = os.path.abspath(args.sweep)
    out = os.path.abspath(args.out)
    try:
        index = mr.read_index(sweep)
    except mr.SchemaError as e:
        print("run_notebooks.py: %s" % e, file=sys.stderr)
        return 2
    for name in ("sweep", "precision", "run"):
        if not os.path.isfile(os.path.join(args.notebooks, name + ".ipynb")):
            print("run_notebooks.py: %s: no such notebook"
                  % os.path.join(args.notebooks, name + ".ipynb"), file=sys.stderr)
            return 2

    # The kernel is started as `python3` from PATH: make it this interpreter, which has the
    # packages (the first python3 on PATH may not), and keep Jupyter's state out of $HOME.
    os.environ["PATH"] = os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", "")
    state = tempfile.mkdtemp(prefix="marglab-jupyter-")
    os.environ.setdefault("JUPYTER_RUNTIME_DIR", os.path.join(state, "runtime"))
    os.environ.setdefault("IPYTHONDIR", os.path.join(state, "ipython"))
    os.environ.setdefault("MPLCONFIGDIR", os.path.join(state, "matplotlib"))
    os.environ["MARGLAB_TOOLS"] = HERE
    os.environ["PYDEVD_DISABLE_FILE_VALIDATION"] = "1"

    nb = lambda name: os.path.join(os.path.abspath(args.notebooks), name + ".ipynb")
    tasks = [(nb("sweep"), os.path.join(out, "sweep"), {"SWEEP": sweep}, args.timeout),
             (nb("precision"), os.path.join(out, "precision"), {"SWEEP": sweep}, args.timeout)]
    # A run gets a notebook when its results file opens; one that does not (truncated, a killed
    # writer's leftover) is skipped with a warning, as tables, plot and report skip it.
    readable = []
    for run_id, path in zip(index["id"], index["path"]):
        if not path or not os.path.isfile(path):
            readable.append(False)
            continue
        try:
            mr.run_summary(path)
            readable.append(True)
        except (OSError, KeyError, ValueError) as e:
            print("warning: %s: not a complete results file (%s); run %s gets no notebook"
                  % (path, e, run_id), file=sys.stderr)
            readable.append(False)
    with_file = index[readable]
    if args.runs == "all":
        ids = list(with_file["id"])
    elif args.runs == "none":
        ids = []
    else:
        ids = [i for i in args.runs.split(",") if i]
        unknown = sorted(set(ids) - set(with_file["id"]))
        if unknown:
            print("run_notebooks.py: no results file for run(s) %s in %s"
                  % (", ".join(unknown), sweep), file=sys.stderr)
            return 2
    for run_id in ids:
        tasks.append((nb("run"), os.path.join(out, "runs", run_id),
                      {"SWEEP": sweep, "RUN": run_id}, args.timeout))

    jobs = args.jobs if args.jobs > 0 else (os.cpu_count() or 1)
    start = time.monotonic()
    print("notebooks: executing %d notebooks on %s (%d in parallel) -> %s"
          % (len(tasks), sweep, jobs, out), flush=True)
    entries = []
    with concurrent.futures.ProcessPoolExecutor(max_workers=jobs) as pool:
        for entry in pool.map(execute, tasks):
            entries.append(entry)
            print("  %-4s %6.1f s  %s" % ("ok" if entry["ok"] else "FAIL", entry["seconds"],
                                           os.path.relpath(entry["html"], out)), flush=True)
            if not entry["ok"]:  # without the terminal colours of IPython's traceback
                print(re.sub(r"\x1b\[[0-9;]*m", "", entry["error"])[-3000:], file=sys.stderr)
    total = time.monotonic() - start
    failed = [e for e in entries if not e["ok"]]
    manifest = {"sweep": sweep, "seconds": round(total, 1), "notebooks": [
        dict(e, ipynb=os.path.relpath(e["ipynb"], out), html=os.path.relpath(e["html"], out))
        for e in entries]}
    os.makedirs(out, exist_ok=True)
    atomic_save.write_text(os.path.join(out, "notebooks.json"), json.dumps(manifest, indent=1))
    print("notebooks: %d executed, %d failed, %.1f s" % (len(entries), len(failed), total))
    return 1 if failed else 0


if __name__ == "__main__":
    atomic_save.run_main(main, "run_notebooks.py")
