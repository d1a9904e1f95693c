"""The one Python reader of marglab's results (schema_version 1 and 2, core/io/results_file.h).

A run (one HDF5 results file) as pandas DataFrames plus its attributes, and a sweep folder as its
index.csv joined with the runs' /summary values. plot_paper.py, check_results.py, make_report.py,
the notebooks (notebooks/*.ipynb) and the tests read the results through this module, so the
schema lives in one place on the Python side.

    import marglab_results as mr
    run = mr.read_run("results/quick/runs/vo__kitti-10__ns-qr-sqrt-f32__s1.h5")
    run.attrs["variant"], run.summary["ate_rmse"]
    run.frames      # one row per frame: t_ns, t_s, is_keyframe, ..., p_est_x/y/z, q_est_x/y/z/w,
                    #   p_gt_x/y/z, ate_error
    run.marg        # one row per marginalization event: frame_index, t_ns, t_s, ..., dEm_x ...
                    #   dEm_random; run.eigenvalues: one ascending array per event
    run.sparsify    # one row per keyframe marginalization of a dense / nfr run (may be empty);
                    #   info_dense_x ... info_sparse_random when the file has them
    run.frontend    # per-frame front-end statistics when the file has /frontend, else None
    sweep = mr.read_sweep("results/quick")   # index.csv + each run's summary (HDF5 values)

Needs numpy, h5py and pandas (Debian: python3-numpy python3-h5py python3-pandas).
"""
import csv
import json
import os

import h5py
import numpy as np

try:
    import pandas as pd
except ImportError:  # check_results.py and plot_paper.py need only numpy and h5py
    pd = None

# ---- the schema ---------------------------------------------------------------------------------

# Every name, type and shape comes from results_schema.json, written by `marglab schema --json`
# from the C++ tables (core/io/results_schema.cpp); test/io fails when the file is out of date.
with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "results_schema.json")) as _f:
    SCHEMA = json.load(_f)
_GROUPS = {g["name"]: g["columns"] for g in SCHEMA["groups"]}
_ATTRS = {a["name"]: a for a in SCHEMA["root_attributes"]}


def _group_columns(group, rows, required=True):
    """Names of a group's one-value-per-row (rows=False: (n, k)) columns, required or optional."""
    return [c["name"] for c in _GROUPS[group]
            if (c["width"] == 0) == rows and c["width"] >= 0 and c["required"] == required]


SCHEMA_VERSIONS = tuple(SCHEMA["readable_versions"])
ROOT_ATTRS = [a["name"] for a in SCHEMA["root_attributes"] if a["required"]]
# Allowed values of the root string attributes that have a fixed set (status, isa, ...).
ATTR_VALUES = {a["name"]: tuple(a["values"]) for a in SCHEMA["root_attributes"] if a["values"]}
FRAME_1D = _group_columns("frames", rows=True)
FRAME_2D = {c["name"]: c["axes"] for c in _GROUPS["frames"] if c["width"] > 0}
MARG_1D = _group_columns("marg", rows=True)
MARG_OPTIONAL_1D = _group_columns("marg", rows=True, required=False)
DEM_DIRECTIONS = next(c["axes"] for c in _GROUPS["marg"] if c["name"] == "dEm")
# Optional (m, 7) columns of /sparsify, along DEM_DIRECTIONS: εᵀΛε of the dense and sparsified prior.
SPARSIFY_INFO = _group_columns("sparsify", rows=False, required=False)
SPARSIFY_1D = _group_columns("sparsify", rows=True)
FRONTEND_1D = _group_columns("frontend", rows=True)
FRONTEND_KINDS = ATTR_VALUES["frontend"]
MARG_STRATEGIES = ATTR_VALUES["marg_strategy"]
SUMMARY_ATTRS = [a["name"] for a in SCHEMA["summary_attributes"]]
# The scalar /summary values, copied into a sweep table (read_sweep) as tables.cpp reads them.
SUMMARY_COLUMNS = [a["name"] for a in SCHEMA["summary_attributes"] if "[" not in a["type"]]
# The kind of number of every dataset, keyed by (group, name): integer ("iub": any width, as
# HDF5 converts on reading, so files from other tools with int64 counts read too) or float ("f").
_KINDS = {"int64": "iub", "int32": "iub", "uint8": "iub", "f64": "f"}
KINDS = {(g["name"], c["name"]): _KINDS[c["type"]] for g in SCHEMA["groups"] for c in g["columns"]}

# Variants as the paper names them (Demmel et al., Tables 1-3).
HEADLINE = ["ns-qr-sqrt-f64", "ns-qr-sqrt-f32", "sc-sc-sq-f64", "sc-sc-sq-f32"]


class SchemaError(Exception):
    """A file that is not a readable marglab results file (message names the file)."""


def decode(value):
    """An HDF5 attribute as a Python value: bytes -> str, numpy scalars -> int / float."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value[()]
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def attributes(obj):
    """All attributes of an h5py object, decoded."""
    return {k: decode(v) for k, v in obj.attrs.items()}


def label(variant, mode):
    """The paper's name of a headline variant (sqrt-VIO-64, VO-32, ...); else the variant."""
    family = "VIO" if mode == "vio" else "VO"
    bits = variant[-2:]
    if variant.startswith("ns-qr-sqrt"):
        return "\u221a%s-%s" % (family, bits)
    if variant.startswith("sc-sc-sq-"):
        return "%s-%s" % (family, bits)
    return variant


def slug(dataset):
    """kitti/10 -> kitti-10 (file names of figures)."""
    return "".join(c if (c.isalnum() or c in "_.-") else "-" for c in dataset).lstrip("-")


# ---- one run ------------------------------------------------------------------------------------

def _columns(group, names, n, where, optional=False):
    out = {}
    for name in names:
        if name not in group:
            if optional:
                continue
            raise SchemaError("%s: missing %s/%s" % (group.file.filename, where, name))
        data = group[name][:]
        kinds = KINDS.get((where.strip("/"), name))
        if kinds is not None and data.dtype.kind not in kinds:
            raise SchemaError("%s: %s/%s is %s, the schema says %s"
                              % (group.file.filename, where, name, data.dtype,
                                 "a float" if kinds == "f" else "an integer"))
        if data.shape != (n,):
            raise SchemaError("%s: %s/%s has shape %s, expected (%d,)"
                              % (group.file.filename, where, name, data.shape, n))
        out[name] = data
    return out


class Run:
    """One results file read into memory (the full priors of /marg/priors stay on disk: prior(k)).

    attrs      root attributes (decoded), with marg_strategy defaulting to "discard", frontend and
               isa to "" when absent
    summary    /summary attributes; R_gt_est as a 3x3 array, t_gt_est as a 3-vector
    frames, marg, sparsify: DataFrames (numpy dicts when pandas is missing); frontend: DataFrame or
    None; eigenvalues: list of ascending arrays, one per /marg row
    """

    def __init__(self, path):
        self.path = path
        try:
            f = h5py.File(path, "r")
        except OSError as e:
            raise SchemaError("%s: cannot open: %s" % (path, e)) from e
        with f:
            self.attrs = attributes(f)
            version = self.attrs.get("schema_version")
            if version not in SCHEMA_VERSIONS:
                raise SchemaError("%s: schema_version %r (this reader knows %s)"
                                  % (path, version, ", ".join(map(str, SCHEMA_VERSIONS))))
            self.attrs.setdefault("marg_strategy", "discard")
            self.attrs.setdefault("frontend", "")
            self.attrs.setdefault("isa", "")
            for name in ("tracks_file", "tracks_sequence", "tracks_any_sequence"):
                self.attrs.setdefault(name, "")
            for group in ("frames", "marg", "summary"):
                if group not in f:
                    raise SchemaError("%s: missing group /%s" % (path, group))
            self.summary = attributes(f["summary"])
            if "R_gt_est" in self.summary:
                self.summary["R_gt_est"] = np.asarray(self.summary["R_gt_est"], float).reshape(3, 3)
            if "t_gt_est" in self.summary:
                self.summary["t_gt_est"] = np.asarray(self.summary["t_gt_est"], float).reshape(3)

            fr = f["frames"]
            n = fr["t_ns"].shape[0] if "t_ns" in fr else 0
            frames = _columns(fr, FRAME_1D, n, "/frames")
            for name, axes in FRAME_2D.items():
                if name not in fr or fr[name].shape != (n, len(axes)):
                    raise SchemaError("%s: /frames/%s missing or not (%d, %d)"
                                      % (path, name, n, len(axes)))
                data = fr[name][:]
                for j, a in enumerate(axes):
                    frames["%s_%s" % (name, a)] = data[:, j]
            self.t0_ns = int(frames["t_ns"][0]) if n else 0
            frames["t_s"] = (frames["t_ns"].astype(np.int64) - self.t0_ns) * 1e-9
            frames["is_keyframe"] = frames["is_keyframe"].astype(bool)

            mg = f["marg"]
            m = mg["frame_index"].shape[0] if "frame_index" in mg else 0
            marg = _columns(mg, MARG_1D, m, "/marg")
            marg.update(_columns(mg, MARG_OPTIONAL_1D, m, "/marg", optional=True))
            if "dEm" not in mg or mg["dEm"].shape != (m, len(DEM_DIRECTIONS)):
                raise SchemaError("%s: /marg/dEm missing or not (%d, 7)" % (path, m))
            dem = mg["dEm"][:]
            for j, d in enumerate(DEM_DIRECTIONS):
                marg["dEm_" + d] = dem[:, j]
            marg["t_s"] = (marg["t_ns"].astype(np.int64) - self.t0_ns) * 1e-9
            self.eigenvalues = []
            if "eigenvalues" in mg:
                values = mg["eigenvalues/values"][:]
                offsets = mg["eigenvalues/offsets"][:]
                if offsets.shape != (m + 1,):
                    raise SchemaError("%s: /marg/eigenvalues/offsets is not (%d,)" % (path, m + 1))
                self.eigenvalues = [values[offsets[k]:offsets[k + 1]] for k in range(m)]
            self.prior_events = sorted(int(k) for k in mg["priors"]) if "priors" in mg else []

            sparsify = {name: np.zeros(0) for name in SPARSIFY_1D}
            if "sparsify" in f and "frame_index" in f["sparsify"]:
                sp = f["sparsify"]
                k = sp["frame_index"].shape[0]
                sparsify = _columns(sp, SPARSIFY_1D, k, "/sparsify")
                sparsify["recovered"] = sparsify["recovered"].astype(bool)
                for name in SPARSIFY_INFO:  # optional: info_dense_x ... info_sparse_random
                    if name in sp:
                        if sp[name].shape != (k, len(DEM_DIRECTIONS)):
                            raise SchemaError("%s: /sparsify/%s is not (%d, 7)" % (path, name, k))
                        for j, d in enumerate(DEM_DIRECTIONS):
                            sparsify["%s_%s" % (name, d)] = sp[name][:, j]

            frontend = None
            if "frontend" in f and "t_ns" in f["frontend"]:
                # Its own rows, keyed by t_ns (the frames the front-end tracked, a superset of
                # /frames; zero rows when the run had no front-end statistics).
                fe = f["frontend"]
                k = fe["t_ns"].shape[0]
                frontend = _columns(fe, [c for c in FRONTEND_1D if c in fe], k, "/frontend")
                for name in fe:  # columns added after this reader: kept when per-row
                    if name not in frontend and fe[name].shape == (k,):
                        frontend[name] = fe[name][:]

        self.frames = _frame(frames)
        self.marg = _frame(marg)
        self.sparsify = _frame(sparsify)
        self.frontend = None if frontend is None else _frame(frontend)

    # -- conveniences
    @property
    def variant(self):
        return self.attrs["variant"]

    @property
    def mode(self):
        return self.attrs.get("mode", "")

    @property
    def status(self):
        return self.attrs["status"]

    @property
    def failure_frame(self):
        return int(self.attrs.get("failure_frame", -1))

    @property
    def dataset_name(self):
        """"kitti/10" as in the sweep index (dataset/sequence attributes)."""
        return "%s/%s" % (self.attrs.get("dataset", ""), self.attrs.get("sequence", ""))

    def name(self):
        return label(self.variant, self.mode)

    def positions(self, which="p_est"):
        return np.column_stack([np.asarray(self.frames["%s_%s" % (which, a)]) for a in "xyz"])

    def aligned(self):
        """Estimated positions in the ground-truth frame (the file's SE(3) alignment)."""
        R = self.summary.get("R_gt_est", np.eye(3))
        t = self.summary.get("t_gt_est", np.zeros(3))
        return self.positions("p_est") @ np.asarray(R).T + np.asarray(t)

    def failure_time(self):
        """Seconds since the first frame at which the run failed; None when it did not."""
        n = len(self.frames["t_ns"])
        if self.status != "failed" or n == 0:
            return None
        k = min(max(self.failure_frame, 0), n - 1)
        return float(np.asarray(self.frames["t_s"])[k])

    def eigenvalue_matrix(self):
        """Events x max(prior_cols) matrix of the prior spectra, NaN-padded (for heat maps)."""
        width = max((len(e) for e in self.eigenvalues), default=0)
        out = np.full((len(self.eigenvalues), width), np.nan)
        for k, e in enumerate(self.eigenvalues):
            out[k, :len(e)] = e
        return out

    def prior(self, k):
        """The full double prior of /marg row k (only every 25th event is stored): dict of arrays."""
        with h5py.File(self.path, "r") as f:
            g = f["marg/priors/%d" % k]
            out = {name: g[name][:] for name in g}
            out.update(attributes(g))
            return out


def _frame(columns):
    if pd is None:
        return columns
    return pd.DataFrame(columns)


def read_run(path):
    """The results file at `path` as a Run; raises SchemaError naming the file."""
    return Run(path)


# ---- a sweep folder -----------------------------------------------------------------------------

def _need_pandas():
    if pd is None:
        raise ImportError("reading a sweep needs pandas (Debian: python3-pandas)")


def _index_path(sweep_dir):
    index = sweep_dir if sweep_dir.endswith(".csv") else os.path.join(sweep_dir, "index.csv")
    if not os.path.isfile(index):
        raise SchemaError("%s: no such file (not a sweep folder; run `marglab sweep`)" % index)
    return index


def _check_utf8(index):
    """SchemaError naming the file and the byte when index.csv is not UTF-8 text."""
    with open(index, "rb") as f:
        data = f.read()
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise SchemaError("%s: byte %d: expected UTF-8 text (a sweep index), found byte 0x%02x"
                          % (index, e.start, data[e.start]))


def read_index_rows(sweep_dir):
    """index.csv as a list of dicts of strings (no pandas needed), `path` = the results file."""
    index = _index_path(sweep_dir)
    base = os.path.dirname(index)
    _check_utf8(index)
    with open(index, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        row["path"] = os.path.join(base, row["results"]) if row.get("results") else ""
    return rows


def recorded_dataset(path, indexed):
    """"<kind>/<sequence>" as the results file records it (a user's folder is indexed by its path,
    "/data/kitti/06"); the indexed name when the file cannot be read."""
    try:
        with h5py.File(path, "r") as f:
            kind, sequence = decode(f.attrs.get("dataset", "")), decode(f.attrs.get("sequence", ""))
    except (OSError, KeyError):
        return indexed
    return "%s/%s" % (kind, sequence) if kind and sequence else indexed


def key_datasets(rows):
    """Sets row["dataset"] of index rows (with "path") to the dataset's identity as
    `marglab tables` keys it: the recorded "<kind>/<sequence>"; two different indexed datasets
    that record the same name (two user folders called 06) keep apart as "kitti/06 (FOLDER)",
    the shipped one keeping the plain name. Returns the warnings about such collisions."""
    indexed = {}
    for row in rows:
        name, path = row["dataset"], row.get("path", "")
        key = recorded_dataset(path, name) if path and os.path.isfile(path) else name
        row["dataset"], row["indexed_dataset"] = key, name
        indexed.setdefault(key, set()).add(name)
    warnings = []
    for key, names in sorted(indexed.items()):
        if len(names) > 1:
            warnings.append("%s: runs on %d datasets record this name (%s): each keeps a row of "
                            "its own, named by its folder" % (key, len(names),
                                                              ", ".join(sorted(names))))
    for row in rows:
        key, name = row["dataset"], row["indexed_dataset"]
        if len(indexed[key]) > 1 and name != key:
            row["dataset"] = "%s (%s)" % (key, name)
    return warnings


def read_index(sweep_dir):
    """index.csv of a sweep as a DataFrame, with `path` = the results file's path (or "")."""
    _need_pandas()
    index = _index_path(sweep_dir)
    _check_utf8(index)
    sweep_dir = os.path.dirname(index)
    # round_trip: the C++ writers print doubles with 17 digits; pandas' default parser may be off
    # by an ulp.
    df = pd.read_csv(index, dtype={"override": str, "results": str, "reason": str,
                                   "failure_kind": str, "group": str},
                     float_precision="round_trip")
    for col in ("override", "results", "reason", "failure_kind"):
        if col in df:
            df[col] = df[col].fillna("")
    df["sweep"] = os.path.basename(os.path.normpath(sweep_dir))
    df["path"] = [os.path.join(sweep_dir, r) if r else "" for r in df["results"]]
    return df


def run_summary(path):
    """The root attributes and /summary values of one file, without reading its datasets."""
    with h5py.File(path, "r") as f:
        a = attributes(f)
        s = attributes(f["summary"]) if "summary" in f else {}
    out = {"state": a.get("status", "missing"), "mode": a.get("mode", ""),
           "marg_strategy": a.get("marg_strategy", "discard"), "frontend": a.get("frontend", ""),
           "schema_version": a.get("schema_version"), "git_sha": a.get("git_sha", ""),
           "marglab_version": a.get("marglab_version", ""),
           "h5_failure_frame": a.get("failure_frame", -1),
           "failure_reason": a.get("failure_reason", "")}
    for name in SUMMARY_COLUMNS:
        out[name] = s.get(name, np.nan)
    return out


def read_sweep(sweep_dir):
    """The sweep's index joined with each run's summary read from its HDF5 file.

    The HDF5 values take the schema's names (ate_rmse, t_opt_total_s, ...; the index's copies get
    the suffix _index); `readable` says whether the run's results file opened. `state` is ok | failed (from the file, or the index when the process died
    without one) | missing (no complete file, not failed) — as `marglab tables` counts them.
    """
    df = read_index(sweep_dir)
    rows = []
    for _, r in df.iterrows():
        values = {}
        if r["path"] and os.path.isfile(r["path"]):
            try:
                values = dict(run_summary(r["path"]), readable=True)
            except (OSError, KeyError) as e:
                values = {"state": "missing", "read_error": str(e)}
        else:
            values = {"state": "failed" if r.get("status") == "failed" else "missing"}
        rows.append(values)
    h5 = pd.DataFrame(rows, index=df.index)
    if "readable" in h5.columns:
        h5["readable"] = h5["readable"].fillna(False).astype(bool)
    # Every column of run_summary, also when no file of the sweep could be read.
    defaults = {"readable": False, "mode": "", "marg_strategy": "discard", "frontend": "",
                "schema_version": np.nan,
                "git_sha": "", "marglab_version": "", "h5_failure_frame": -1,
                "failure_reason": ""}
    defaults.update({name: np.nan for name in SUMMARY_COLUMNS})
    for name, value in defaults.items():
        if name not in h5.columns:
            h5[name] = value
    overlap = [c for c in h5.columns if c in df.columns]
    df = df.rename(columns={c: c + "_index" for c in overlap})
    return pd.concat([df, h5], axis=1)


def read_tables(sweep_dir):
    """<sweep>/tables/tables.csv (written by `marglab tables`): one row per cell, ours and the
    paper's; None when the tables have not been written."""
    _need_pandas()
    path = os.path.join(sweep_dir, "tables", "tables.csv")
    if not os.path.isfile(path):
        return None
    return pd.read_csv(path, dtype={"override": str, "frames": str}, keep_default_na=False,
                       na_values=[""], float_precision="round_trip")


def failure_matrix(sweep):
    """Variants x datasets: 'ok', 'failed @ N' (failure frame), or '' (not run); cells with several
    seeds or overrides join their states."""
    _need_pandas()

    def cell(group):
        parts = []
        for _, r in group.iterrows():
            if r["state"] == "ok":
                parts.append("ok")
            elif r["state"] == "failed":
                frame = r.get("h5_failure_frame")
                if frame is None or (isinstance(frame, float) and np.isnan(frame)):
                    frame = r.get("failure_frame")
                frame = "" if frame is None or (isinstance(frame, float) and np.isnan(frame)) \
                    else " @ %d" % int(frame)
                parts.append("failed" + frame)
            else:
                parts.append(r["state"])
        return ", ".join(parts)

    table = sweep.groupby(["variant", "dataset"]).apply(cell).unstack("dataset").fillna("")
    order = [v for v in HEADLINE if v in table.index] + \
        sorted(v for v in table.index if v not in HEADLINE)
    return table.loc[order]


def precision_pairs(sweep):
    """f32 and f64 runs of the same method, dataset, seed and override: one row per pair with
    both summaries (columns *_f32, *_f64) and the ATE difference f32 - f64 (NaN unless both
    runs finished)."""
    _need_pandas()
    keys = ["dataset", "method", "seed", "override"]
    cols = keys + ["id", "state", "ate_rmse", "t_opt_total_s", "t_marg_total_s", "path",
                   "h5_failure_frame", "readable"]
    a = sweep[sweep["precision"] == "f32"][cols]
    b = sweep[sweep["precision"] == "f64"][cols]
    pairs = a.merge(b, on=keys, suffixes=("_f32", "_f64"))
    both_ok = (pairs["state_f32"] == "ok") & (pairs["state_f64"] == "ok")
    pairs["ate_f32_minus_f64"] = (pairs["ate_rmse_f32"] - pairs["ate_rmse_f64"]).where(both_ok)
    return pairs.sort_values(keys).reset_index(drop=True)
