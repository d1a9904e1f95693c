#!/usr/bin/env python3
"""Independent check of a marglab results file (schema_version 1 or 2, docs/design.md §6).

Usage: check_results.py RUN.h5

Checks that every attribute and dataset of the schema exists with consistent shapes, that the ragged
/marg/eigenvalues agree with /marg (one ascending row of prior_cols values per event), that
/sparsify agrees with the marg_strategy attribute (equal column lengths, rows only for dense / nfr,
frame_index within /frames, nnz_sparse <= nnz_dense and KLD >= 0 where the prior was recovered, KLD
NaN where it was kept dense, the optional info_dense / info_sparse both (rows, 7) and equal where it
was kept dense), that /frontend agrees with the frontend attribute (images / simulated / tracks;
equal column lengths, t_ns strictly increasing and, unless it has zero rows, containing every
/frames t_ns, n_features = n_tracked + n_new, 0 <= n_stereo <= n_features, t_frontend_s finite and
>= 0 for images; both absent in files written before the front-end existed), that every attribute
with a fixed set of values (status, isa, mode, ...) has one of them, and recomputes the ATE from
/frames (p_est vs p_gt, rows where both are finite) with a numpy Umeyama/Kabsch alignment without
scale (reflection fix diag(1, 1, det(U V^T))), comparing it with /summary ate_rmse and
/frames/ate_error. Prints "OK ..." and exits 0, or lists every problem and exits 1 (2 for usage
errors).

The schema's names and allowed attribute values come from marglab_results.py, which reads them from
results_schema.json (generated from the C++ tables, core/io/results_schema.cpp); the checks
themselves read the file with h5py directly and recompute everything they compare, independently of
the C++ writer and of that reader. Needs only numpy and h5py.
"""
import os
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from marglab_results import (ATTR_VALUES, FRAME_1D, FRONTEND_1D, FRONTEND_KINDS,  # noqa: E402
                             MARG_1D, MARG_STRATEGIES, ROOT_ATTRS, SCHEMA_VERSIONS, SPARSIFY_1D,
                             SPARSIFY_INFO, SUMMARY_ATTRS, decode)
import marglab_results  # noqa: E402

FRAME_2D = {name: len(axes) for name, axes in marglab_results.FRAME_2D.items()}


def umeyama(src, dst):
    """(rot, trans) minimizing Σ‖dst − (rot src + trans)‖², rot ∈ SO(3) (no scale)."""
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    sigma = (dst - mu_d).T @ (src - mu_s) / len(src)
    u, _, vt = np.linalg.svd(sigma)
    s = np.diag([1.0, 1.0, np.sign(np.linalg.det(u) * np.linalg.det(vt)) or 1.0])
    rot = u @ s @ vt
    return rot, mu_d - rot @ mu_s


def umeyama_rmse(src, dst):
    rot, trans = umeyama(src, dst)
    err = np.linalg.norm(dst - (src @ rot.T + trans), axis=1)
    return float(np.sqrt(np.mean(err ** 2))), err


def close(a, b, scale):
    return abs(a - b) <= 1e-9 * max(scale, 1e-3)


def check_sparsify(f, n_frames):
    """/sparsify against the marg_strategy attribute; both are absent in files written before the
    strategies existed (which marginalized as discard does)."""
    problems = []
    strategy = f.attrs.get("marg_strategy")
    if strategy is None:
        return problems if "sparsify" not in f else ["/sparsify without a marg_strategy attribute"]
    strategy = str(decode(strategy))
    if strategy not in MARG_STRATEGIES:
        return [f"marg_strategy {strategy!r} is not one of {', '.join(MARG_STRATEGIES)}"]
    if "sparsify" not in f:
        return ["missing group /sparsify"]
    sp = f["sparsify"]
    missing = [name for name in SPARSIFY_1D if name not in sp]
    if missing:
        return [f"missing /sparsify/{name}" for name in missing]
    lengths = {name: sp[name].shape for name in SPARSIFY_1D}
    if len(set(lengths.values())) != 1 or len(next(iter(lengths.values()))) != 1:
        return [f"/sparsify columns differ in shape: {lengths}"]
    col = {name: sp[name][:] for name in SPARSIFY_1D}
    rows = col["frame_index"].shape[0]
    if strategy == "discard" and rows:
        problems.append(f"{rows} /sparsify rows in a discard run")
    if np.any((col["frame_index"] < 0) | (col["frame_index"] >= n_frames)):
        problems.append(f"/sparsify/frame_index outside /frames (0..{n_frames - 1})")
    recovered = col["recovered"].astype(bool)
    if strategy == "dense" and recovered.any():
        problems.append("/sparsify/recovered set in a dense run")
    if np.any(col["nnz_sparse"][recovered] > col["nnz_dense"][recovered]):
        problems.append("/sparsify: nnz_sparse > nnz_dense where the prior was recovered")
    if np.any(col["nnz_sparse"][~recovered] != col["nnz_dense"][~recovered]):
        problems.append("/sparsify: nnz_sparse != nnz_dense where the prior was kept dense")
    kld = col["kld"]
    if np.any(kld[recovered] < 0):  # NaN compares False: allowed
        problems.append("/sparsify/kld negative where the prior was recovered")
    if not np.all(np.isnan(kld[~recovered])):
        problems.append("/sparsify/kld not NaN where the prior was kept dense")
    return problems + check_sparsify_info(sp, rows, recovered)


def check_sparsify_info(sp, rows, recovered):
    """The optional (rows, 7) information columns: both or neither; a kept prior is its own."""
    present = [name for name in SPARSIFY_INFO if name in sp]
    if not present:
        return []
    if len(present) != len(SPARSIFY_INFO):
        return [f"/sparsify has {present[0]} without the other information column"]
    info = {name: sp[name][:] for name in SPARSIFY_INFO}
    if any(v.shape != (rows, 7) for v in info.values()):
        return [f"/sparsify information columns are not ({rows}, 7)"]
    dense, sparse = info["info_dense"], info["info_sparse"]
    if not np.array_equal(dense[~recovered], sparse[~recovered], equal_nan=True):
        return ["/sparsify: info_sparse != info_dense where the prior was kept dense"]
    return []


def check_frontend(f, frame_t_ns):
    """/frontend against the frontend attribute (both absent in older files: simulated tracks)."""
    kind = f.attrs.get("frontend")
    if kind is None:
        return [] if "frontend" not in f else ["/frontend without a frontend attribute"]
    kind = str(decode(kind))
    if kind not in FRONTEND_KINDS:
        return [f"frontend {kind!r} is not one of {', '.join(FRONTEND_KINDS)}"]
    if "frontend" not in f:
        return ["missing group /frontend"]
    fe = f["frontend"]
    missing = [name for name in FRONTEND_1D if name not in fe]
    if missing:
        return [f"missing /frontend/{name}" for name in missing]
    lengths = {fe[name].shape for name in FRONTEND_1D}
    if len(lengths) != 1 or len(next(iter(lengths))) != 1:
        return [f"/frontend columns differ in shape: {lengths}"]
    problems = []
    t = fe["t_ns"][:]
    if np.any(np.diff(t) <= 0):
        problems.append("/frontend/t_ns not strictly increasing")
    if t.size and not np.all(np.isin(frame_t_ns, t)):  # zero rows: no statistics were given
        problems.append("/frames/t_ns has frames without a /frontend row")
    n_features, n_tracked, n_new, n_stereo = (fe[c][:].astype(np.int64) for c in
                                              ("n_features", "n_tracked", "n_new", "n_stereo"))
    if np.any(n_tracked < 0) or np.any(n_new < 0) or np.any(n_features != n_tracked + n_new):
        problems.append("/frontend: n_features != n_tracked + n_new (or negative counts)")
    if np.any(n_stereo < 0) or np.any(n_stereo > n_features):
        problems.append("/frontend: n_stereo outside 0..n_features")
    t_fe = fe["t_frontend_s"][:]
    if kind == "images" and (not np.all(np.isfinite(t_fe)) or np.any(t_fe < 0)):
        problems.append("/frontend/t_frontend_s not finite and >= 0 in an images run")
    return problems


def check(path):
    return check_file(path)[0]


def check_file(path):
    """(problems, values): the list of problems and what was recomputed (`ate_numpy`, the RMSE of
    the numpy alignment, NaN without pairs; `ate_file`, /summary ate_rmse; `n_pairs`)."""
    problems = []
    values = {}
    with h5py.File(path, "r") as f:
        for name in ROOT_ATTRS:
            if name not in f.attrs:
                problems.append(f"missing root attribute {name}")
        version = decode(f.attrs.get("schema_version"))
        if version not in SCHEMA_VERSIONS:
            problems.append(f"schema_version {version} is not one of "
                            f"{', '.join(map(str, SCHEMA_VERSIONS))}")
        for name, allowed in ATTR_VALUES.items():  # status, isa, ... (absent: checked above)
            if name in f.attrs and decode(f.attrs[name]) not in allowed:
                problems.append(f"{name} {f.attrs[name]!r} is not one of "
                                f"{', '.join(map(repr, allowed))}")
        for group in ["frames", "marg", "marg/eigenvalues", "summary"]:
            if group not in f:
                problems.append(f"missing group /{group}")
        if problems:
            return problems, values

        fr = f["frames"]
        n = fr["t_ns"].shape[0] if "t_ns" in fr else -1
        for name in FRAME_1D:
            if name not in fr:
                problems.append(f"missing /frames/{name}")
            elif fr[name].shape != (n,):
                problems.append(f"/frames/{name} has shape {fr[name].shape}, expected ({n},)")
        for name, cols in FRAME_2D.items():
            if name not in fr:
                problems.append(f"missing /frames/{name}")
            elif fr[name].shape != (n, cols):
                problems.append(f"/frames/{name} has shape {fr[name].shape}, expected ({n}, {cols})")

        mg = f["marg"]
        m = mg["frame_index"].shape[0] if "frame_index" in mg else -1
        for name in MARG_1D:
            if name not in mg:
                problems.append(f"missing /marg/{name}")
            elif mg[name].shape != (m,):
                problems.append(f"/marg/{name} has shape {mg[name].shape}, expected ({m},)")
        if "dEm" not in mg or mg["dEm"].shape != (m, 7):
            problems.append("missing /marg/dEm or shape != (M, 7)")
        eg = mg["eigenvalues"]
        if "values" not in eg or "offsets" not in eg:
            problems.append("missing /marg/eigenvalues/values or offsets")
        else:
            offsets = eg["offsets"][:]
            values = eg["values"][:]
            if offsets.shape != (m + 1,) or offsets[0] != 0 or offsets[-1] != values.shape[0]:
                problems.append("/marg/eigenvalues/offsets inconsistent with /marg and values")
            elif "prior_cols" in mg:
                counts = np.diff(offsets)
                if not np.array_equal(counts, mg["prior_cols"][:]):
                    problems.append("eigenvalue counts differ from /marg/prior_cols")
                for k in range(m):
                    row = values[offsets[k]:offsets[k + 1]]
                    finite = row[np.isfinite(row)]
                    if finite.size and np.any(np.diff(finite) < 0):
                        problems.append(f"eigenvalues of event {k} are not ascending")
                    if finite.size and "sigma_min" in mg and finite.size == row.size:
                        if finite[0] != mg["sigma_min"][k] or finite[-1] != mg["sigma_max"][k]:
                            problems.append(f"sigma_min/max of event {k} differ from its eigenvalues")

        problems += check_sparsify(f, n)
        problems += check_frontend(f, fr["t_ns"][:])

        summary = f["summary"].attrs
        for name in SUMMARY_ATTRS:
            if name not in summary:
                problems.append(f"missing /summary attribute {name}")
        if problems:
            return problems, values
        if summary["n_frames"] != n:
            problems.append(f"/summary n_frames {summary['n_frames']} != {n} rows")

        p_est, p_gt = fr["p_est"][:], fr["p_gt"][:]
        ok = np.all(np.isfinite(p_est), axis=1) & np.all(np.isfinite(p_gt), axis=1)
        stored_rmse = float(summary["ate_rmse"])
        ate_error = fr["ate_error"][:]
        if not ok.any():
            if not np.isnan(stored_rmse):
                problems.append(f"no GT pairs but ate_rmse = {stored_rmse}")
        else:
            rmse, err = umeyama_rmse(p_est[ok], p_gt[ok])
            scale = float(np.abs(p_gt[ok]).max())
            if not close(rmse, stored_rmse, scale):
                problems.append(f"ATE mismatch: numpy {rmse:.12g} vs /summary {stored_rmse:.12g}")
            if not np.allclose(err, ate_error[ok], rtol=0, atol=1e-9 * max(scale, 1e-3)):
                problems.append("per-frame /frames/ate_error differs from the numpy alignment")
            if not np.all(np.isnan(ate_error[~ok])):
                problems.append("/frames/ate_error is not NaN where there is no GT pair")
        values = {"ate_numpy": umeyama_rmse(p_est[ok], p_gt[ok])[0] if ok.any() else float("nan"),
                  "ate_file": stored_rmse, "n_pairs": int(ok.sum()), "schema_version": version}
        print(f"ATE (numpy Umeyama, {values['n_pairs']} pairs): {values['ate_numpy']:.9g} m, "
              f"file: {stored_rmse:.9g} m")
    return problems, values


def main(argv):
    if len(argv) != 2:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    try:
        problems = check(argv[1])
    except (OSError, KeyError) as e:
        print(f"{argv[1]}: cannot read: {e}", file=sys.stderr)
        return 1
    if problems:
        for p in problems:
            print(f"{argv[1]}: {p}", file=sys.stderr)
        return 1
    with h5py.File(argv[1], "r") as f:
        version = decode(f.attrs.get("schema_version"))
    print(f"OK {argv[1]}: schema_version {version}, all datasets present, ATE consistent")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
