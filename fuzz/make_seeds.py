#!/usr/bin/env python3
"""Builds the committed text seed corpus of the fuzzers (fuzz/corpus/<target>/) from the shipped
data: the first lines of each dataset file kind, the calibration files, the experiments' sweep
files and the configs inside them. Run from anywhere; rewrites fuzz/corpus/ (except the crash
regression inputs, fuzz/corpus/*/crash-*, which stay). fuzz_track_content's seeds are
fuzz_track_hdf5's committed track files (fuzz/README.md says how they were made) in that harness's
binary form (read with h5py); the captured windows are decompressed from datasets/windows by
fuzz/run_fuzzers.sh.

The harnesses that serve several parsers read the parser from the first byte (fuzz_dataset_text:
byte % 6, fuzz_calib: byte % 4); the digits '0'..'5' select parser 0..5 since ord('0') = 48.
"""
import gzip
import pathlib
import re
import tomllib

ROOT = pathlib.Path(__file__).resolve().parent.parent
DATA = ROOT / "datasets"
CORPUS = ROOT / "fuzz" / "corpus"
LINES = 12  # lines per dataset seed: enough for every per-line check, small for the fuzzer


def head(path, lines=LINES):
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", newline="") as f:
        return "".join(line for _, line in zip(range(lines), f))


def write(target, name, text):
    folder = CORPUS / target
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_text(text, newline="")


def dataset_text():
    seeds = {  # selector digit -> files
        "0": ["euroc/MH_01_easy/gt_tum.txt.gz", "tumvi/magistrale1/estimate_vinsmono_tum.txt.gz"],
        "1": ["euroc/V2_03_difficult/gt_asl.csv.gz", "tumvi/room1/gt_asl.csv.gz"],
        "2": ["tumvi/room1/imu0_asl.csv.gz", "euroc/V2_03_difficult/imu0_asl.csv.gz"],
        "3": ["euroc/MH_01_easy/cam0_timestamps_ns.txt.gz",
              "euroc/V1_01_easy_images/mav0/cam0/data.csv"],
        "4": ["kitti/00/times.txt.gz"],
        "5": ["kitti/00/poses.txt.gz"],
    }
    for selector, files in seeds.items():
        for f in files:
            name = f.replace("/", "_").removesuffix(".gz")  # the seed itself is plain text
            write("dataset_text", f"{selector}-{name}", selector + head(DATA / f))


def calib():
    seeds = {
        "0": ["euroc/calib/cam0_sensor.yaml", "euroc/V1_01_easy_images/mav0/cam1/sensor.yaml"],
        "1": ["euroc/calib/openvins_kalibr_imucam_chain.yaml",
              "tumvi/calib/openvins_kalibr_imucam_chain.yaml"],
        "2": ["euroc/calib/openvins_kalibr_imu_chain.yaml",
              "tumvi/calib/openvins_kalibr_imu_chain.yaml"],
        "3": ["kitti/00/calib.txt"],
    }
    for selector, files in seeds.items():
        for f in files:
            text = (DATA / f).read_text()
            write("calib", f"{selector}-{f.replace('/', '_')}", selector + text)


def sweeps_and_configs():
    for sweep in sorted((ROOT / "experiments").glob("*.toml")):
        text = sweep.read_text()
        write("sweep", sweep.name, text)
        # The inline configs of the sweep's groups and overrides are estimator configs.
        n = 0
        for group in tomllib.loads(text).get("group", []):
            for table in [group.get("config")] + [o.get("config") for o in group.get("override", [])]:
                if table:
                    write("config", f"{sweep.stem}-{n}.toml", toml_text(table))
                    n += 1
    write("config", "empty.toml", "")
    # Every key: the config written into a captured window ("config <n>" then n bytes).
    window = gzip.open(DATA / "windows" / "kitti-00_ns-qr-sqrt-f32_000100.win.gz", "rb").read()
    m = re.search(rb"\nconfig (\d+)\n", window)
    start = m.end()
    write("config", "full.toml", window[start:start + int(m.group(1))].decode())


def toml_text(table):
    """Nested tables of scalars as TOML (enough for the estimator config's layout)."""
    out = []
    for section, values in table.items():
        out.append(f"[{section}]")
        for key, value in values.items():
            out.append(f"{key} = {toml_value(value)}")
    return "\n".join(out) + "\n"


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v + '"'
    return repr(v)


def track_text():
    # A few frames in the documented format (core/sim/track_io.h), with every optional part.
    write("track_text", "stereo.txt",
          "# marglab-tracks text 1\n# sequence: kitti/00\n# seed: 1\n"
          "0 0 100.5 200.25 90.5 200.25 3 0\n0 1 300 50 nan nan -1 0\n"
          "100000000 0 101.5 201 91 201 3 0\n100000000 2 10 20 5 20 7 1\n200000000\n"
          "300000000 2 11 21 nan nan\n")


def track_content():
    """fuzz_track_content's seeds: the committed track files, decoded by h5py into the harness's
    binary form (fuzz/fuzz_track_content.cpp)."""
    import struct

    import h5py
    import numpy

    def text(s):
        b = s.encode()
        return struct.pack("<B", len(b)) + b

    def column(values, dtype):
        a = numpy.asarray(values, dtype=dtype)
        return struct.pack("<I", len(a)) + a.tobytes()

    for name in ["tracked2", "tracked3"]:
        with h5py.File(CORPUS / "track_hdf5" / f"{name}.h5", "r") as f:
            o = f["observations"]
            out = text(f.attrs["format"]) + struct.pack("<i", f.attrs["format_version"])
            out += text(f.attrs["sequence"]) + struct.pack("<q", f.attrs["seed"])
            out += column(f["frames/t_ns"][()], "<i8")
            for c in ["offsets", "track_id", "landmark_id"]:
                out += column(o[c][()], "<i8")
            for c in ["u0", "v0", "u1", "v1"]:
                out += column(o[c][()], "<f8")
            for c in ["has_right", "is_outlier"]:
                out += column(o[c][()], "u1")
            xyz = f["landmarks_w"][()] if "landmarks_w" in f else None
            out += struct.pack("<B", 0) if xyz is None else (
                struct.pack("<BIB", 1, xyz.shape[0], xyz.shape[1]) + xyz.astype("<f8").tobytes())
        folder = CORPUS / "track_content"
        folder.mkdir(parents=True, exist_ok=True)
        (folder / f"{name}.bin").write_bytes(out)


def main():
    for target in ["dataset_text", "calib", "sweep", "config", "track_text", "track_content"]:
        folder = CORPUS / target
        if folder.exists():
            for f in folder.iterdir():
                if not f.name.startswith("crash-"):
                    f.unlink()
    dataset_text()
    calib()
    sweeps_and_configs()
    track_text()
    track_content()


if __name__ == "__main__":
    main()
