"""HDF5 recordings and MATLAB v7.3 .mat files (HDF5 inside), on small generated files."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io

from mjjoint.recordings import RecordingError, parse_column_map, read_recording

N = 50
DT = 1e-3


def signals(seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {"t": np.arange(N) * DT, "u": rng.normal(size=N), "q": rng.normal(size=N) * 50,
            "theta": rng.normal(size=N), "tau": rng.normal(size=N) * 100}


def write_mat73(path: Path, variables: dict) -> None:
    """A MATLAB v7.3 file as MATLAB writes one: a 512-byte user block with the MAT header, every
    array stored with its dimensions reversed (column-major), structs as groups, a class per node."""
    with h5py.File(path, "w", userblock_size=512) as f:
        def put(group: h5py.Group, name: str, value) -> None:
            if isinstance(value, dict):
                g = group.create_group(name)
                g.attrs["MATLAB_class"] = np.bytes_("struct")
                for k, v in value.items():
                    put(g, k, v)
                return
            if isinstance(value, str):
                d = group.create_dataset(name, data=np.frombuffer(value.encode("utf-16-le"), np.uint16)[:, None])
                d.attrs["MATLAB_class"] = np.bytes_("char")
                return
            a = np.asarray(value, float)
            a = a[:, None] if a.ndim == 1 else a  # MATLAB has no 1-D arrays: a vector is N x 1
            d = group.create_dataset(name, data=a.T)
            d.attrs["MATLAB_class"] = np.bytes_("double")
        for name, value in variables.items():
            put(f, name, value)
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Thu Nov 26 00:00:00 2026 HDF5 schema 1.00 ."
    with path.open("r+b") as f:
        f.write(header.ljust(116) + bytes(8) + b"\x00\x02IM")


def assert_signals(rec, expected: dict[str, np.ndarray]) -> None:
    got = rec.signals()
    assert list(got) == list(expected)
    for name, x in expected.items():
        np.testing.assert_array_equal(got[name], x, err_msg=name)


def test_mat73_reads_like_the_same_v5_file(tmp_path: Path) -> None:
    """Struct fields by dotted path and matrix columns: a v7.3 file gives what its v5 twin gives."""
    s = signals()
    data = np.column_stack([s["u"], s["q"], np.zeros(N)])  # N x 3, one signal per column
    variables = {"rec": {"time_cont": s["t"], "link": {"theta": s["theta"], "tau": s["tau"]}}, "data": data}
    columns = parse_column_map("t=rec.time_cont,u=data[:, 0],q=data[:,1],theta=rec.link.theta,tau=rec.link.tau")
    write_mat73(tmp_path / "v73.mat", variables)
    scipy.io.savemat(tmp_path / "v5.mat", {"rec": {"time_cont": s["t"][:, None],
                                                   "link": {"theta": s["theta"][:, None], "tau": s["tau"][:, None]}},
                                           "data": data})
    v73 = read_recording(tmp_path / "v73.mat", columns=columns)
    assert_signals(v73, s)
    assert_signals(read_recording(tmp_path / "v5.mat", columns=columns), v73.signals())
    assert v73.meta["format"] == "mat"


def test_mat73_top_level_canonical_names_need_no_map(tmp_path: Path) -> None:
    s = signals(1)
    write_mat73(tmp_path / "rec.mat", {**s, "gain": np.array([[2.0]]), "comment": "axis 1"})
    assert_signals(read_recording(tmp_path / "rec.mat"), s)


@pytest.mark.parametrize("suffix", [".h5", ".hdf5"])
def test_plain_hdf5_by_slash_and_dotted_paths(tmp_path: Path, suffix: str) -> None:
    s = signals(2)
    path = tmp_path / f"log{suffix}"
    with h5py.File(path, "w") as f:
        f["/drive/time"] = s["t"]
        f["/drive/meas"] = np.column_stack([s["q"], s["theta"]])  # N x 2 as h5py writes it (row-major)
        f["/drive/cmd"] = s["u"]
        f["tau"] = s["tau"]
    rec = read_recording(path, columns=parse_column_map("t=/drive/time,u=drive.cmd,q=drive/meas[:, 0],theta=/drive/meas[:,1]"))
    assert_signals(rec, s)


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("/drive/tim", ["'drive' has no member 'tim'", "'time'"]),
        ("motor.time", ["the file has no member 'motor'", "'drive'"]),
        ("drive", ["is a group with members", "drive.NAME"]),
        ("drive/time/x", ["'drive/time' is a dataset of shape (50,)"]),
        ("drive/meas", ["shape (50, 2)", "drive/meas[:, j]"]),
        ("drive/meas[:, 2]", ["column 2 is out of range for shape (50, 2)"]),
        ("refs", ["holds references"]),
    ],
)
def test_hdf5_source_errors_name_the_path(tmp_path: Path, source: str, expected: list[str]) -> None:
    path = tmp_path / "log.h5"
    with h5py.File(path, "w") as f:
        f["/drive/time"] = np.arange(N) * DT
        f["/drive/meas"] = np.zeros((N, 2))
        refs = f.create_dataset("refs", (2,), dtype=h5py.ref_dtype)
        refs[0] = f["/drive/time"].ref
    with pytest.raises(RecordingError) as err:
        read_recording(path, columns={"t": source, "u": "drive/time", "q": "drive/time", "theta": "drive/time"})
    message = str(err.value)
    assert "\n" not in message and str(path) in message and "(for t)" in message
    for part in expected:
        assert part in message


def test_mat73_non_numeric_variable_is_refused(tmp_path: Path) -> None:
    write_mat73(tmp_path / "rec.mat", {**signals(), "name": "axis 1"})
    with pytest.raises(RecordingError, match="'name' \\(for theta\\) is a MATLAB char array"):
        read_recording(tmp_path / "rec.mat", columns={"theta": "name"})


@pytest.mark.parametrize("suffix", [".h5", ".mat"])
def test_corrupt_hdf5_is_one_line_and_untouched(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"bad{suffix}"
    write_mat73(path, signals())
    data = bytearray(path.read_bytes())
    data[512:1024] = bytes(512)  # the HDF5 superblock and root group gone
    path.write_bytes(bytes(data))
    before = path.stat().st_mtime_ns
    with pytest.raises(RecordingError) as err:
        read_recording(path)
    assert "\n" not in str(err.value) and "not a readable" in str(err.value) and "HDF5" in str(err.value)
    assert path.read_bytes() == bytes(data) and path.stat().st_mtime_ns == before
