#!/usr/bin/env python3
"""One self-contained HTML page of a sweep: the page a researcher sends to a colleague.

Usage: make_report.py --sweep results/NAME --out notebooks-out/NAME [--figures DIR] [--tables DIR]

Writes OUT/report.html with the sweep's configuration (sweep.toml), the git revision(s) and
marglab version(s) that wrote the results files, the failure matrix (variants x sequences), the
paper's tables with ours beside them (the Markdown of `marglab tables`, TABLES/tables*.md), the
figures (the PNGs of `marglab plot` in FIGURES, default OUT, embedded as base64) and links to the
executed notebooks of `marglab notebooks` (OUT/notebooks.json: sweep, precision, one per run).
Nothing is loaded from the network and the page runs no script. Exit 0, 1 when the sweep cannot be
read, 2 for usage errors. Needs numpy, h5py, pandas (Debian: python3-numpy python3-h5py
python3-pandas).
"""
import argparse
import base64
import datetime
import html
import json
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
try:
    import numpy as np
    import pandas as pd  # noqa: F401
    sys.path.insert(0, HERE)
    import atomic_save
    import marglab_results as mr
except ImportError as e:
    print("make_report.py: %s. Install the Debian packages: sudo apt-get install python3-numpy "
          "python3-h5py python3-pandas" % e, file=sys.stderr)
    sys.exit(3)

CAPTIONS = [
    (r"fig1_(.*)", "Fig. 1 analog ({}): trajectories of the four headline variants against the "
                   "reference (top) and the smallest eigenvalue of the gauge-free prior (bottom; "
                   "symlog, linear within ±1e-8)."),
    (r"fig4_dEm_(.*)", "Fig. 4 analog ({}): ΔE_m (eq. 27) along x, y, z, roll, pitch, yaw and a "
                       "random direction, one panel per variant."),
    (r"fig4_yaw_(.*)", "Fig. 4's finding ({}): |ΔE_m(yaw)| / min(|ΔE_m(roll)|, |ΔE_m(pitch)|) at "
                       "every marginalization, every seed, one panel per variant; near 1 = yaw "
                       "as observable as roll and pitch (onset frames in fig4_yaw_*.csv)."),
    (r"fig5_dEm_(.*)", "Fig. 5 analog ({}): ΔE_m along the seven directions, VO."),
    (r"fig6_sigma_min_(.*)", "Fig. 6 analog ({}): σ_min of the gauge-free prior over time."),
    (r"fig7_trajectory_(.*)", "Fig. 7 analog ({}): trajectories, top-down."),
    (r"sparsify_fig6a", "Hsiung et al. Fig. 6a analog: optimization and marginalization time of "
                        "every keyframe (nfr)."),
    (r"sparsify_fig6b", "Hsiung et al. Fig. 6b analog: box plots of the times per frame, per "
                        "keyframe marginalization and of its steps."),
    (r"sparsify_kld", "D_KL of every recovered event over time (nfr runs)."),
]

CSS = """
body { font: 14px/1.45 -apple-system, 'Segoe UI', Roboto, 'DejaVu Sans', sans-serif; margin: 0;
       color: #1d232a; background: #fff; }
main { max-width: 1180px; margin: 0 auto; padding: 24px 32px 64px; }
h1 { font-size: 26px; margin: 8px 0 4px; } h2 { font-size: 20px; margin-top: 36px;
  border-bottom: 2px solid #e3e7ec; padding-bottom: 4px; } h3 { font-size: 16px; margin: 22px 0 6px; }
.sub { color: #5a6673; margin: 0 0 12px; }
.meta td { padding: 2px 14px 2px 0; vertical-align: top; } .meta td:first-child { color: #5a6673; }
table.data { border-collapse: collapse; margin: 6px 0 10px; font-size: 13px; }
table.data th, table.data td { border: 1px solid #d5dbe2; padding: 3px 8px; text-align: right; }
table.data th { background: #f2f5f8; } table.data td:first-child, table.data th:first-child
  { text-align: left; }
td.ok { background: #dff2df; } td.failed { background: #f7d4d4; font-weight: 600; }
td.none { background: #fafafa; color: #9aa4ae; }
table.data td.t { text-align: left; }
pre { background: #f6f8fa; border: 1px solid #e3e7ec; padding: 10px; overflow-x: auto;
      font-size: 12px; }
.note { color: #5a6673; font-size: 12.5px; margin: 2px 0; }
figure { margin: 18px 0 28px; }
figure img { max-width: 100%; max-height: 760px; border: 1px solid #e3e7ec; }
figcaption { color: #3d4650; font-size: 13px; margin-top: 4px; }
nav a { margin-right: 14px; } a { color: #0b62c4; }
.tables-grid { overflow-x: auto; }
"""


def esc(value):
    return html.escape("" if value is None else str(value))


def inline_md(text):
    """Bold, code and escapes of one Markdown line of the tables (no links, no raw HTML)."""
    out = esc(text)
    out = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", out)
    out = re.sub(r"`([^`]+)`", r"<code>\1</code>", out)
    out = re.sub(r"^_(.+)_$", r"<i>\1</i>", out)
    return out


def markdown_tables(text):
    """The Markdown `marglab tables` writes (### headings, pipe tables, note lines) as HTML."""
    out, rows = [], []

    def flush():
        if not rows:
            return
        cells = [[c.strip() for c in r.strip().strip("|").split("|")] for r in rows]
        head, body = cells[0], [r for r in cells[2:]] if len(cells) > 1 and \
            set("".join(cells[1])) <= set("-: ") else cells[1:]
        out.append('<table class="data"><thead><tr>' +
                   "".join("<th>%s</th>" % inline_md(c) for c in head) + "</tr></thead><tbody>")
        for r in body:
            out.append("<tr>" + "".join("<td>%s</td>" % inline_md(c) for c in r) + "</tr>")
        out.append("</tbody></table>")
        rows.clear()

    for line in text.splitlines():
        if line.startswith("|"):
            rows.append(line)
            continue
        flush()
        if line.startswith("#"):
            level = min(len(line) - len(line.lstrip("#")), 4)
            out.append("<h%d>%s</h%d>" % (max(level, 3), inline_md(line.lstrip("#").strip()),
                                          max(level, 3)))
        elif line.strip():
            out.append('<p class="note">%s</p>' % inline_md(line.strip().lstrip("-* ")))
    flush()
    return "\n".join(out)


def caption(stem):
    for pattern, text in CAPTIONS:
        m = re.fullmatch(pattern, stem)
        if m:
            return text.format(*(g.replace("-", "/", 1) for g in m.groups()))
    return stem


def figure_html(path):
    with open(path, "rb") as f:
        data = base64.b64encode(f.read()).decode("ascii")
    stem = os.path.splitext(os.path.basename(path))[0]
    return ('<figure id="%s"><img alt="%s" src="data:image/png;base64,%s">'
            "<figcaption><b>%s</b> — %s</figcaption></figure>"
            % (esc(stem), esc(stem), data, esc(stem), esc(caption(stem))))


def failure_matrix_html(sweep):
    fm = mr.failure_matrix(sweep)
    head = "<tr><th>variant \\ sequence</th>" + "".join("<th>%s</th>" % esc(c)
                                                       for c in fm.columns) + "</tr>"
    body = []
    for variant, row in fm.iterrows():
        cells = []
        for value in row:
            cls = "failed" if "failed" in value else ("ok" if value == "ok" else "none")
            cells.append('<td class="%s">%s</td>' % (cls, esc(value or "–")))
        body.append("<tr><td>%s</td>%s</tr>" % (esc(variant), "".join(cells)))
    return ('<table class="data" id="failure-matrix"><thead>%s</thead><tbody>%s</tbody></table>'
            % (head, "".join(body)))


def failed_runs_html(sweep):
    failed = sweep[sweep["state"] == "failed"]
    if failed.empty:
        return '<p class="note">No run failed.</p>'
    rows = []
    for _, r in failed.iterrows():
        reason = r.get("failure_reason") if isinstance(r.get("failure_reason"), str) and \
            r.get("failure_reason") else r.get("reason", "")
        frame = r.get("h5_failure_frame")
        if frame is None or (isinstance(frame, float) and np.isnan(frame)):
            frame = r.get("failure_frame", "")
        rows.append("<tr><td>%s</td><td>%s</td><td>%s</td><td style='text-align:left'>%s</td>"
                    "</tr>" % (esc(r["id"]), esc(r.get("failure_kind", "")),
                               esc("" if frame is None or frame != frame else int(frame)),
                               esc(reason)))
    return ('<table class="data"><thead><tr><th>run</th><th>kind</th><th>frame</th>'
            "<th style='text-align:left'>reason</th></tr></thead><tbody>%s</tbody></table>"
            % "".join(rows))


def fmt(value, digits=4):
    try:
        v = float(value)
    except (TypeError, ValueError):
        return esc(value)
    if v != v:
        return "–"
    return "%.*f" % (digits, v)


def runs_html(sweep, notebooks, out):
    by_run = {n["params"].get("RUN"): n for n in notebooks if n["params"].get("RUN")}
    rows = []
    for _, r in sweep.iterrows():
        nb = by_run.get(r["id"])
        link = "–"
        if nb and os.path.isfile(os.path.join(out, nb["html"])):
            link = '<a href="%s">notebook</a>%s' % (esc(nb["html"]),
                                                   "" if nb["ok"] else " (failed)")
        cls = "ok" if r["state"] == "ok" else ("failed" if r["state"] == "failed" else "none")
        rows.append("<tr><td>%s</td><td class='t'>%s</td><td class='t'>%s</td><td class='%s'>%s</td><td>%s</td>"
                    "<td>%s</td><td>%s</td><td>%s</td></tr>"
                    % (esc(r["id"]), esc(r["dataset"]), esc(r["variant"]), cls, esc(r["state"]),
                       fmt(r.get("n_frames"), 0), fmt(r.get("ate_rmse")),
                       fmt(r.get("realtime_factor"), 1), link))
    return ('<table class="data" id="runs"><thead><tr><th>run</th><th>sequence</th>'
            "<th>variant</th><th>state</th><th>frames</th><th>ATE [m]</th>"
            "<th>real-time factor</th><th>notebook</th></tr></thead><tbody>%s</tbody></table>"
            % "".join(rows))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sweep", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--figures", default="", help="folder of the PNG figures (default OUT)")
    parser.add_argument("--tables", default="", help="folder of tables*.md (default SWEEP/tables)")
    args = parser.parse_args()
    sweep_dir, out = args.sweep, args.out
    figures_dir = args.figures or out
    tables_dir = args.tables or os.path.join(sweep_dir, "tables")
    try:
        sweep = mr.read_sweep(sweep_dir)
    except (mr.SchemaError, OSError, ValueError) as e:
        print("make_report.py: %s" % e, file=sys.stderr)
        return 1
    name = os.path.basename(os.path.normpath(sweep_dir))
    os.makedirs(out, exist_ok=True)

    config_path = os.path.join(sweep_dir, "sweep.toml")
    config = open(config_path, encoding="utf-8").read() if os.path.isfile(config_path) else ""
    description = ""
    m = re.search(r'^description\s*=\s*"(.*)"\s*$', config, re.M)
    if m:
        description = m.group(1)
    shas = sorted(set(s for s in sweep.get("git_sha", pd.Series(dtype=str)).dropna() if s))
    versions = sorted(set(s for s in sweep.get("marglab_version",
                                               pd.Series(dtype=str)).dropna() if s))
    counts = sweep["state"].value_counts()

    manifest_path = os.path.join(out, "notebooks.json")
    notebooks, nb_seconds = [], None
    if os.path.isfile(manifest_path):
        with open(manifest_path) as f:
            manifest = json.load(f)
        notebooks, nb_seconds = manifest.get("notebooks", []), manifest.get("seconds")

    tables_md = ""
    if os.path.isdir(tables_dir):
        for f in sorted(os.listdir(tables_dir)):  # tables.md, tables__<override>.md
            if re.fullmatch(r"tables(__.+)?\.md", f):
                tables_md += ("\n## override %s\n" % f[8:-3] if f != "tables.md" else "") + \
                    open(os.path.join(tables_dir, f), encoding="utf-8").read() + "\n"
    figures = []
    if os.path.isdir(figures_dir):
        figures = sorted(os.path.join(figures_dir, f) for f in os.listdir(figures_dir)
                         if f.endswith(".png") and (f.startswith("fig") or
                                                     f.startswith("sparsify")))

    parts = ['<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">',
             '<meta name="viewport" content="width=device-width, initial-scale=1">',
             "<title>marglab report: %s</title><style>%s</style></head><body><main>"
             % (esc(name), CSS)]
    parts.append("<h1>marglab sweep <code>%s</code></h1>" % esc(name))
    parts.append('<p class="sub">%s</p>' % esc(description))
    parts.append('<nav><a href="#configuration">configuration</a><a href="#failures">failure '
                 'matrix</a><a href="#tables">tables</a><a href="#figures">figures</a>'
                 '<a href="#notebooks">notebooks</a></nav>')
    meta = [("sweep folder", esc(os.path.abspath(sweep_dir))),
            ("runs", esc(", ".join("%d %s" % (n, s) for s, n in counts.items()))),
            ("git revision", ", ".join("<code>%s</code>" % esc(s) for s in shas) or "–"),
            ("marglab", esc(", ".join(versions) or "–")),
            ("report written", esc(datetime.datetime.now(datetime.timezone.utc)
                                   .strftime("%Y-%m-%d %H:%M UTC")))]
    parts.append('<table class="meta">%s</table>' % "".join(
        "<tr><td>%s</td><td>%s</td></tr>" % kv for kv in meta))

    parts.append('<h2 id="configuration">Configuration</h2>')
    parts.append("<pre>%s</pre>" % esc(config) if config else
                 '<p class="note">No sweep.toml in %s.</p>' % esc(sweep_dir))

    parts.append('<h2 id="failures">Failure matrix</h2>')
    parts.append('<p class="note">Variants × sequences: ok, or failed @ the row of /frames where '
                 "the run failed (from the results files).</p>")
    parts.append(failure_matrix_html(sweep))
    parts.append(failed_runs_html(sweep))

    parts.append('<h2 id="tables">The paper\'s tables, ours beside them</h2>')
    if tables_md:
        parts.append('<div class="tables-grid">%s</div>' % markdown_tables(tables_md))
    else:
        parts.append('<p class="note">No tables in %s: run <code>marglab tables %s</code>.</p>'
                     % (esc(tables_dir), esc(sweep_dir)))

    parts.append('<h2 id="figures">Figures</h2>')
    if figures:
        parts.extend(figure_html(p) for p in figures)
    else:
        parts.append('<p class="note">No figures in %s: run <code>marglab plot %s</code>.</p>'
                     % (esc(figures_dir), esc(sweep_dir)))

    parts.append('<h2 id="notebooks">Notebooks</h2>')
    if notebooks:
        links = []
        for key, title in (("sweep.ipynb", "the sweep"), ("precision.ipynb",
                                                          "f32 against f64, frame by frame")):
            for n in notebooks:
                if n["notebook"] == key and "RUN" not in n["params"]:
                    links.append('<li><a href="%s">%s</a> (%s)%s</li>'
                                 % (esc(n["html"]), esc(title), esc(key),
                                    "" if n["ok"] else " — failed"))
        parts.append("<ul>%s</ul>" % "".join(links))
        parts.append('<p class="note">Executed by <code>marglab notebooks</code> in %s s; each '
                     "run's notebook is linked below.</p>" % esc(nb_seconds))
    else:
        parts.append('<p class="note">No executed notebooks here: run <code>marglab notebooks '
                     "%s</code>.</p>" % esc(sweep_dir))
    parts.append(runs_html(sweep, notebooks, out))
    parts.append("</main></body></html>\n")

    path = os.path.join(out, "report.html")
    atomic_save.write_text(path, "\n".join(parts))
    print("report: %s (%d figures, %d notebooks linked)" % (path, len(figures), len(notebooks)))
    return 0


if __name__ == "__main__":
    atomic_save.run_main(main, "make_report.py")
