"""Recordings I/O: round trips, column mapping and scales, and rejection of bad files."""

from __future__ import annotations

import dataclasses
import io
import json
import re
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.io
import scipy.sparse
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mjjoint.recordings import (
    DEG,
    MultiRecording,
    Recording,
    RecordingError,
    parse_column_map,
    parse_scales,
    read_recording,
    reading_notes,
    write_recording,
)
from mjjoint.recordings.resample import nominal_period

N = 50
DT = 1e-3


def make_recording(n: int = N, tau: bool = True, seed: int = 0) -> Recording:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    return Recording(
        t=t,
        u=rng.normal(size=n),
        q=rng.normal(size=n) * 50,
        theta=rng.normal(size=n),
        tau=rng.normal(size=n) * 100 if tau else None,
        gear_ratio=100.0,
    )


def csv_text(header: str, rows: list[list[object]]) -> str:
    return header + "\n" + "".join(",".join(str(v) for v in row) + "\n" for row in rows)


def valid_rows(n: int = 20) -> list[list[object]]:
    return [[repr(i * DT), 0.1 * i, 0.2 * i, 0.01 * i, 0.5] for i in range(n)]


def assert_same_signals(a: Recording | MultiRecording, b: Recording | MultiRecording) -> None:
    sa, sb = a.signals(), b.signals()
    assert list(sa) == list(sb)
    for name in sa:
        np.testing.assert_array_equal(sa[name], sb[name], err_msg=name)


# --- round trips -----------------------------------------------------------------------


@pytest.mark.parametrize("suffix, sep, decimal, preamble", [
    (".tsv", "\t", ".", ""),
    (".csv", ";", ",", ""),                                # a spreadsheet's export in a decimal-comma locale
    (".dat", "   ", ".", "# rig 3, 2026-05-01\n% gains: kp=4\n"),  # an instrument's text table
    (".txt", " \t ", ",", "# exported\n"),
])
def test_text_tables_read_with_their_own_separator(tmp_path: Path, suffix, sep, decimal, preamble) -> None:
    rec = make_recording(tau=True)
    signals = rec.signals()
    rows = ["\n".join(sep.join(repr(v).replace(".", decimal) for v in row)
                      for row in np.column_stack(list(signals.values())).tolist())]
    path = tmp_path / f"rec{suffix}"
    path.write_text(preamble + sep.join(signals) + "\n" + rows[0] + "\n\n")
    assert_same_signals(rec, read_recording(path, gear_ratio=100.0))


@pytest.mark.parametrize("form, zone", [("%Y-%m-%d %H:%M:%S.%f", ""), ("%Y-%m-%dT%H:%M:%S.%f", "+02:00")])
def test_a_time_column_of_iso_stamps_is_seconds_from_the_first(tmp_path: Path, form: str, zone: str) -> None:
    """A logger's wall-clock stamps (pandas writes them so), across midnight, to the microsecond."""
    from datetime import datetime, timedelta
    rec = make_recording(tau=False)
    first = datetime(2026, 5, 1, 23, 59, 59, 990000)
    stamps = [(first + timedelta(seconds=float(t))).strftime(form) + zone for t in rec.t]
    path = tmp_path / "log.csv"
    path.write_text("time,u,q,theta\n" + "".join(f"{a},{u:.17g},{q:.17g},{th:.17g}\n" for a, u, q, th in
                                                 zip(stamps, rec.u, rec.q, rec.theta)))
    got = read_recording(path, columns={"t": "time"}, gear_ratio=100.0)
    np.testing.assert_allclose(got.t, rec.t, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(got.q, rec.q)
    bad = path.read_text().splitlines()
    bad[5] = "12:00," + bad[5].split(",", 1)[1]
    path.write_text("\n".join(bad) + "\n")
    with pytest.raises(RecordingError, match="line 6, column 'time': '12:00' is not a time stamp like the first"):
        read_recording(path, columns={"t": "time"}, gear_ratio=100.0)


@pytest.mark.parametrize("tau", [True, False])
def test_csv_round_trip_is_exact(tmp_path: Path, tau: bool) -> None:
    rec = make_recording(tau=tau)
    path = tmp_path / "rec.csv"
    write_recording(path, rec)
    header = path.read_text().splitlines()[0]
    assert header == ("t,u,q,theta,tau" if tau else "t,u,q,theta")
    back = read_recording(path, gear_ratio=100.0)
    assert isinstance(back, Recording)
    assert_same_signals(rec, back)
    assert back.gear_ratio == 100.0
    assert back.meta["source"] == str(path)


def test_multi_joint_round_trip(tmp_path: Path) -> None:
    j1, j2 = make_recording(seed=1), make_recording(tau=False, seed=2)
    multi = MultiRecording((j1, j2))
    path = tmp_path / "multi.csv"
    write_recording(path, multi)
    assert path.read_text().splitlines()[0] == "t,u1,q1,theta1,tau1,u2,q2,theta2"
    back = read_recording(path)
    assert isinstance(back, MultiRecording)
    assert back.n_joints == 2
    assert_same_signals(multi, back)
    assert back.joint(2).tau is None
    assert back.joint(1).meta["joint"] == 1
    with pytest.raises(IndexError):
        back.joint(0)


def finite(bound: float) -> st.SearchStrategy[float]:
    return st.floats(min_value=-bound, max_value=bound, allow_nan=False, allow_subnormal=True)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.lists(st.tuples(finite(1e5), finite(1e5), finite(1e3), finite(1e5)), min_size=10, max_size=30), jitter=st.floats(0, 0.4))
def test_round_trip_any_floats(tmp_path: Path, data: list[tuple[float, ...]], jitter: float) -> None:
    u, q, theta, tau = (np.array(c) for c in zip(*data))
    t = 3.0 + np.arange(len(u)) * DT + jitter * DT * (np.arange(len(u)) % 2)
    rec = Recording(t=t, u=u, q=q, theta=theta, tau=tau)
    path = tmp_path / "any.csv"
    write_recording(path, rec)
    back = read_recording(path)
    if back.meta["resampled"] is None:  # uniform timestamps: read back exactly as written
        assert_same_signals(rec, back)
    else:  # jitter: every signal interpolated linearly onto the uniform grid
        assert jitter > 0 and back.t[0] == t[0]
        for name, x in rec.signals().items():
            np.testing.assert_array_equal(getattr(back, name), np.interp(back.t, t, x) if name != "t" else back.t)


# --- mapping, scales, formats ----------------------------------------------------------


def test_csv_column_map_and_degree_scales(tmp_path: Path) -> None:
    rec = make_recording()
    q_deg, theta_deg = rec.q / DEG, rec.theta / DEG
    rows = [[repr(float(v)) for v in row] for row in zip(rec.t, rec.u, q_deg, theta_deg)]
    path = tmp_path / "logged.csv"
    path.write_text(csv_text("time,torque,motor_deg,link_deg", rows))
    back = read_recording(
        path,
        columns=parse_column_map("t=time, u=torque, q=motor_deg, theta=link_deg"),
        scales=parse_scales("q=deg,theta=deg,u=2.5"),
    )
    np.testing.assert_array_equal(back.q, q_deg * DEG)
    np.testing.assert_array_equal(back.theta, theta_deg * DEG)
    np.testing.assert_array_equal(back.u, rec.u * 2.5)
    assert back.tau is None
    assert back.meta["columns"] == {"t": "time", "u": "torque", "q": "motor_deg", "theta": "link_deg"}


def test_npz_column_map_and_scales(tmp_path: Path) -> None:
    rec = make_recording()
    path = tmp_path / "rec.npz"
    np.savez(path, time=rec.t, cmd=rec.u, qm=rec.q / DEG, ql=rec.theta / DEG, gain=np.array(3.0))
    back = read_recording(path, columns={"t": "time", "u": "cmd", "q": "qm", "theta": "ql"}, scales={"q": DEG, "theta": DEG})
    np.testing.assert_array_equal(back.q, rec.q / DEG * DEG)
    np.testing.assert_array_equal(back.theta, rec.theta / DEG * DEG)
    np.testing.assert_array_equal(back.t, rec.t)


def test_mat_column_vectors_rows_and_scales(tmp_path: Path) -> None:
    rec = make_recording()
    path = tmp_path / "rec.mat"
    # MATLAB vectors arrive as N x 1; a 2-D array holds one signal per row.
    positions = np.vstack([rec.q / DEG, rec.theta / DEG, np.zeros(N)])
    scipy.io.savemat(path, {"time": rec.t[:, None], "vir": rec.u[None, :], "pos_deg": positions, "kp": 2.0})
    back = read_recording(
        path,
        columns=parse_column_map("t=time,u=vir,q=pos_deg[0],theta=pos_deg[1]"),
        scales=parse_scales("q=deg,theta=deg"),
    )
    np.testing.assert_array_equal(back.t, rec.t)
    np.testing.assert_array_equal(back.u, rec.u)
    np.testing.assert_array_equal(back.q, rec.q / DEG * DEG)
    np.testing.assert_array_equal(back.theta, rec.theta / DEG * DEG)


@pytest.mark.parametrize(
    ("columns", "expected"),
    [
        ({"u": "volts", "q": "pos_deg[0]", "theta": "pos_deg[1]"}, ["'volts' (for u) not found", "'vir'", "'pos_deg'"]),
        ({"u": "vir", "q": "pos_deg", "theta": "pos_deg[1]"}, ["shape (2, 50)", "pos_deg[i, :]", "pos_deg[:, j]"]),
        ({"u": "vir", "q": "pos_deg[0]", "theta": "pos_deg[2]"}, ["row 2 is out of range for shape (2, 50)", "0..1"]),
        ({"u": "vir", "q": "pos_deg[0]", "theta": "name"}, ["not a real numeric array"]),
        ({"u": "vir"}, ["missing required variable(s) q, theta", "'pos_deg'"]),
    ],
)
def test_mat_bad_mapping_names_the_variables(tmp_path: Path, columns: dict[str, str], expected: list[str]) -> None:
    path = tmp_path / "rec.mat"
    scipy.io.savemat(path, {"t": np.arange(N) * DT, "vir": np.zeros(N), "pos_deg": np.zeros((2, N)), "name": "axis 1"})
    with pytest.raises(RecordingError) as err:
        read_recording(path, columns=columns)
    assert str(path) in str(err.value)
    for part in expected:
        assert part in str(err.value)


def test_mat_struct_fields_by_dotted_path(tmp_path: Path) -> None:
    rec = make_recording()
    path = tmp_path / "struct.mat"
    # A MATLAB struct `rec` with a nested struct `rec.link`, as save() writes it.
    scipy.io.savemat(path, {"rec": {"time_cont": rec.t[:, None], "u": rec.u, "q": rec.q, "link": {"theta": rec.theta}}})
    back = read_recording(path, columns=parse_column_map("t=rec.time_cont,u=rec.u,q=rec.q,theta=rec.link.theta"))
    assert_same_signals(make_recording(tau=False), back)


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("rec.time", ["struct 'rec' has no field 'time'", "'time_cont'"]),
        ("rec", ["is a struct with fields", "rec.FIELD"]),
        ("rec.time_cont.x", ["'rec.time_cont' is not a struct"]),
        ("other.t", ["not found", "'rec'"]),
        ("arr.t", ["'arr' is a struct array of shape (1, 2)"]),
        ("data[:, -1]", ["column -1 is out of range for shape (50, 7)", "0..6", "no negative"]),
        ("data[:, 7]", ["column 7 is out of range for shape (50, 7)", "0..6"]),
        ("data[0]", ["data[0] is row 0 (7 values) of shape (50, 7)", "write data[:, 0]"]),
        ("data[:, :]", ["unsupported index [:, :]", "NAME[:, j]"]),
        ("data[1:3]", ["unsupported index [1:3]"]),
        ("data[:, 1", ["cannot parse", "NAME[:, j]"]),
        ("cube[:, 0]", ["column index needs a 2-D array, got shape (50, 2, 2)"]),
    ],
)
def test_source_errors_name_the_path_and_shape(tmp_path: Path, source: str, expected: list[str]) -> None:
    path = tmp_path / "struct.mat"
    struct_array = np.array([[(np.zeros(N),), (np.ones(N),)]], dtype=[("t", object)])  # MATLAB arr(1).t, arr(2).t
    scipy.io.savemat(path, {"rec": {"time_cont": np.arange(N) * DT}, "arr": struct_array, "data": np.zeros((N, 7)), "cube": np.zeros((N, 2, 2))})
    with pytest.raises(RecordingError) as err:
        read_recording(path, columns={"t": source, "u": "rec.time_cont", "q": "rec.time_cont", "theta": "rec.time_cont"})
    message = str(err.value)
    assert "\n" not in message and str(path) in message and "(for t)" in message
    for part in expected:
        assert part in message


@pytest.mark.parametrize("suffix", [".mat", ".npz"])
def test_matrix_columns_by_index(tmp_path: Path, suffix: str) -> None:
    rec = make_recording()
    data = np.column_stack([rec.t, rec.u, rec.q, rec.theta, rec.tau, np.zeros(N), np.ones(N)])  # N x 7
    path = tmp_path / f"matrix{suffix}"
    if suffix == ".mat":
        scipy.io.savemat(path, {"data": data})
    else:
        np.savez(path, data=data)
    back = read_recording(path, columns=parse_column_map("t=data[:,0],u=data[:, 1],q=data[ :,2 ],theta=data[:, 3],tau=data[:,4]"))
    assert_same_signals(rec, back)


def test_parquet_columns_and_a_vector_per_sample(tmp_path: Path) -> None:
    """A robot dataset's table: a column per scalar, a list column per joint vector (its
    entries picked as matrix columns), time stamps as a timestamp type, a string column."""
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq
    rec = make_recording()
    start = np.datetime64("2026-05-01T12:00:00", "ns")
    table = pa.table({"timestamp": pa.array(start + np.round(rec.t * 1e9).astype("timedelta64[ns]")),
                      "action": rec.u, "observation.state": [[a, b, c] for a, b, c in zip(rec.theta, rec.q, rec.tau)],
                      "episode": ["a"] * N})
    path = tmp_path / "episode.parquet"
    pq.write_table(table, path)
    back = read_recording(path, columns=parse_column_map(
        "t=timestamp,u=action,q=observation.state[:, 1],theta=observation.state[:, 0],tau=observation.state[:,2]"))
    np.testing.assert_allclose(back.t - back.t[0], rec.t, atol=1e-9)
    for name in ("u", "q", "theta", "tau"):
        np.testing.assert_array_equal(getattr(back, name), getattr(rec, name), err_msg=name)
    with pytest.raises(RecordingError, match="'episode'.* not found; available variables"):
        read_recording(path, columns=parse_column_map("t=timestamp,u=episode,q=action,theta=action"))


def _json_forms(rec: Recording) -> dict[str, object]:
    records = [{"t": t, "u": u, "motor": {"q": q}, "theta": th, "tau": tau, "mode": "run"}
               for t, u, q, th, tau in zip(rec.t, rec.u, rec.q, rec.theta, rec.tau)]
    return {
        "records": records,
        "arrays": {"t": list(rec.t), "u": list(rec.u), "motor": {"q": list(rec.q)}, "theta": list(rec.theta),
                   "tau": list(rec.tau)},
        "log": {"kp": 400, "motor": "xl330", "entries": records},
    }


@pytest.mark.parametrize("form", ["records", "arrays", "log", "lines"])
def test_json_records_arrays_and_logs(tmp_path: Path, form: str) -> None:
    rec = make_recording()
    forms = _json_forms(rec)
    if form == "lines":
        path = tmp_path / "rec.jsonl"
        path.write_text("\n".join(json.dumps(r) for r in forms["records"]) + "\n")
    else:
        path = tmp_path / "rec.json"
        path.write_text(json.dumps(forms[form]))
    prefix = "entries." if form == "log" else ""
    names = {"t": "t", "u": "u", "q": "motor.q", "theta": "theta", "tau": "tau"}
    back = read_recording(path, columns={k: prefix + v for k, v in names.items()})
    assert_same_signals(rec, back)


def test_json_without_samples_and_a_missing_value(tmp_path: Path) -> None:
    path = tmp_path / "settings.json"
    path.write_text(json.dumps({"kp": 400, "name": "servo"}))
    with pytest.raises(RecordingError, match="no list of samples"):
        read_recording(path)
    rec = make_recording()
    records = _json_forms(rec)["records"]
    del records[7]["u"]
    path = tmp_path / "gap.json"
    path.write_text(json.dumps(records))
    with pytest.raises(RecordingError, match="u"):
        read_recording(path, columns={"q": "motor.q"})
    back = read_recording(path, columns={"q": "motor.q"}, allow_gaps=True)
    assert back.u[7] == pytest.approx(0.5 * (rec.u[6] + rec.u[8]))


def test_column_map_keeps_commas_inside_brackets() -> None:
    assert parse_column_map("t=data[:, 0], q=rec.q,u=data[:,1]") == {"t": "data[:, 0]", "q": "rec.q", "u": "data[:,1]"}


# --- timestamps: jitter, clock drift, gaps ----------------------------------------------


def jittered_csv(path: Path, t: np.ndarray) -> None:
    """Signals linear in time (so linear interpolation is exact) at the given timestamps."""
    rows = [[repr(float(x)), 0.5 * x, 2.0 * x + 1.0, -x, 3.0] for x in t]
    path.write_text(csv_text("t,u,q,theta,tau", rows))


def test_jittered_drifting_clock_is_resampled_to_the_nominal_rate(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    n, jitter = 2000, 0.3 * DT
    t = 10.0 + np.arange(n) / 1000.02 + rng.uniform(-jitter, jitter, n)  # 1000.02 Hz clock, jittered stamps
    path = tmp_path / "jitter.csv"
    jittered_csv(path, t)
    rec = read_recording(path)
    info = rec.meta["resampled"]
    assert info["method"] == "linear interpolation" and info["rate"] == 1000.0 and info["samples_in"] == n
    assert rec.n == info["samples_out"] and rec.t[0] == t[0] and rec.t[-1] <= t[-1]
    assert abs(rec.dt * 1000.0 - 1.0) < 1e-9  # the model's rate check (1/timestep divided by an integer) holds
    assert 0.2 * DT < info["max_timestamp_deviation"] < 0.31 * DT
    assert info["max_step_deviation"] < 0.61 * DT
    np.testing.assert_allclose(rec.q, 2.0 * rec.t + 1.0, rtol=1e-12)
    np.testing.assert_allclose(rec.u, 0.5 * rec.t, rtol=1e-12)


def test_uniform_recording_is_left_as_recorded(tmp_path: Path) -> None:
    path = tmp_path / "uniform.csv"
    t = 170.0 + np.arange(N) * DT
    jittered_csv(path, t)
    rec = read_recording(path)
    assert rec.meta["resampled"] is None
    np.testing.assert_array_equal(rec.t, t)


def test_unix_time_stamps_are_a_uniform_clock(tmp_path: Path) -> None:
    """Unix time (1.7e9 s) is stored to 2.4e-7 s: a uniform 1 kHz clock there steps unevenly by
    that much, which is the storage, not jitter to resample (it was, with a note of it)."""
    path = tmp_path / "unix.csv"
    t = 1.7e9 + np.arange(N) * DT
    k = np.arange(N) * DT
    path.write_text(csv_text("t,u,q,theta,tau", [[repr(float(a)), np.sin(b), b, b / 160, 0.1 * b] for a, b in zip(t, k)]))
    rec = read_recording(path)
    assert np.ptp(np.diff(rec.t)) > 1e-7  # the stored steps are uneven
    assert rec.meta["resampled"] is None
    np.testing.assert_array_equal(rec.t, t)


@pytest.mark.parametrize(
    ("step", "timestep", "tolerance", "expected"),
    [
        (1 / 1000.02, None, 1e-4, 1e-3),
        (3e-3 * (1 + 1e-5), None, 1e-4, 3e-3),  # 333.33 Hz: a round period
        (1 / 2999.9, None, 1e-4, 1 / 3000),  # a round rate
        (1 / 1234.5, None, 1e-6, 1 / 1234.5),  # no round number close enough: as measured
        (0.99e-3, 5e-4, 0.0, 1e-3),  # a multiple of the model timestep
        (1e-4, 5e-4, 0.0, 5e-4),
    ],
)
def test_nominal_period_is_round(step: float, timestep: float | None, tolerance: float, expected: float) -> None:
    assert nominal_period(step, timestep, tolerance) == pytest.approx(expected, rel=1e-12)


def test_gap_is_refused_where_it_is_unless_allowed(tmp_path: Path) -> None:
    t = np.arange(N) * DT
    t[30:] += 10 * DT  # 11 periods between samples 29 and 30
    path = tmp_path / "gap.csv"
    jittered_csv(path, t)
    with pytest.raises(RecordingError) as err:
        read_recording(path)
    message = str(err.value)
    for part in ["gap in time before sample 30 (line 32)", "11.0x the median period", "allow_gaps=True (--allow-gaps)"]:
        assert part in message
    rec = read_recording(path, allow_gaps=True)
    assert rec.n == N + 10 and rec.meta["resampled"]["largest_step"] == pytest.approx(11 * DT)
    np.testing.assert_allclose(rec.q, 2.0 * rec.t + 1.0, rtol=1e-12)


def test_repeated_rows_are_dropped(tmp_path: Path) -> None:
    t = np.arange(N) * DT
    path = tmp_path / "repeats.csv"
    jittered_csv(path, np.insert(t, [5, 20, 20], t[[4, 19, 19]]))  # rows 4 and 19 written again (19 twice)
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.t, t)
    np.testing.assert_allclose(rec.q, 2.0 * t + 1.0, rtol=1e-12)
    assert rec.meta["repaired"] == {"repeated_rows": 3, "dropouts": 0} and rec.meta["resampled"] is None
    assert reading_notes(rec.meta) == ["dropped 3 row(s) repeating the one before (same time and values)"]


def test_dropouts_are_refused_unless_gaps_are_allowed_then_interpolated(tmp_path: Path) -> None:
    t = np.arange(N) * DT
    path = tmp_path / "dropouts.csv"
    rows = [[repr(float(x)), 0.5 * x, 2.0 * x + 1.0, -x, 3.0] for x in t]
    rows[10][2] = "nan"
    path.write_text(csv_text("t,u,q,theta,tau", rows[:30]))
    with pytest.raises(RecordingError, match=r"'q' has nan at sample 10 \(line 12\).*--allow-gaps"):
        read_recording(path)
    rec = read_recording(path, allow_gaps=True)
    np.testing.assert_array_equal(rec.t, t[:30])
    np.testing.assert_allclose(rec.q, 2.0 * t[:30] + 1.0, rtol=1e-12)  # sample 10 interpolated across
    assert rec.meta["repaired"] == {"repeated_rows": 0, "dropouts": 1}
    assert reading_notes(rec.meta)[0] == "dropped 1 sample(s) with a non-finite value, interpolated across"


@pytest.mark.parametrize(("unit", "wrap"), [(1.0, lambda a: (a + np.pi) % (2 * np.pi) - np.pi),  # [-pi, pi) in rad
                                           (np.pi / 180, lambda a: np.degrees(a) % 360.0)])  # [0, 360) in degrees
def test_an_angle_read_within_one_turn_is_unwrapped(tmp_path: Path, unit: float, wrap) -> None:
    t = np.arange(2000) / 1000.0
    q = 9.0 * np.sin(2 * np.pi * t) + 0.2  # +-1.4 turns: wraps in both directions
    path = tmp_path / "wrapped.csv"
    path.write_text(csv_text("t,u,q,theta", [[repr(float(a)), 0.1, float(b), float(c)]
                                              for a, b, c in zip(t, wrap(q), q / 100.0 / unit)]))
    rec = read_recording(path, scales={"q": unit, "theta": unit})
    turns = np.round((rec.q[0] - q[0]) / (2 * np.pi))  # the reading's first value fixes the turn
    np.testing.assert_allclose(rec.q, q + 2 * np.pi * turns, atol=1e-9)
    np.testing.assert_allclose(rec.theta, q / 100.0, atol=1e-9)  # never wrapped
    assert set(rec.meta["unwrapped"]) == {"q"} and rec.meta["unwrapped"]["q"] >= 4
    assert reading_notes(rec.meta)[0].startswith("unwrapped q (")


def test_a_jump_that_is_not_whole_turns_is_left_to_the_checks(tmp_path: Path) -> None:
    t = np.arange(N) * DT
    q = np.where(t < 0.02, 0.0, 4.5)  # 4.5 rad in one sample: 1.8 rad off a whole turn
    path = tmp_path / "jump.csv"
    path.write_text(csv_text("t,u,q,theta", [[repr(float(a)), 0.1, float(b), 0.0] for a, b in zip(t, q)]))
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.q, q)
    assert rec.meta["unwrapped"] is None


# --- large angles: a spinning shaft, degrees, counts --------------------------------------


def spinning(path: Path, name: str, rate: float = 1000.0, revs_per_s: float = 50.0, unit: float = 1.0,
             counts: bool = False, start: float = 0.0) -> np.ndarray:
    """10 s of a shaft turning at a constant speed (500 revolutions at the defaults) as signal `name`."""
    t = np.arange(int(10 * rate)) / rate
    angle = (start + 2 * np.pi * revs_per_s * t + 1e-3 * np.sin(7 * t)) * unit
    angle = np.round(angle) if counts else angle
    np.savez(path, t=t, u=np.zeros_like(t), **{"q": np.zeros_like(t), "theta": np.zeros_like(t), name: angle})
    return angle


@pytest.mark.parametrize(("name", "start"), [("theta", 0.0), ("q", 2e6)])  # q: a multi-turn encoder, far from 0
def test_spinning_shaft_in_rad_is_accepted(tmp_path: Path, name: str, start: float) -> None:
    angle = spinning(tmp_path / "spin.npz", name, start=start)  # 500 revolutions in 10 s
    assert np.abs(angle).max() > {"q": 1e6, "theta": 3e3}[name]  # past the limit for the kind
    np.testing.assert_array_equal(getattr(read_recording(tmp_path / "spin.npz"), name), angle)


@pytest.mark.parametrize(
    ("name", "kwargs", "expected"),
    [
        ("theta", {"unit": 1 / DEG}, ["jumps by 18 at sample", "over 1 rad per sample", "looks like degrees", "--scales theta=deg"]),
        ("q", {"unit": 4096 / (2 * np.pi), "counts": True}, ["every value is a whole number", "encoder counts", "q=FACTOR", "2*pi/(counts per revolution)"]),
        ("theta", {"rate": 1e5, "revs_per_s": 2000.0}, ["moves at 1.257e+04 per s at sample", "over 10000 rad/s", "degrees or counts"]),
    ],
)
def test_large_angle_in_degrees_or_counts_is_refused(tmp_path: Path, name: str, kwargs: dict, expected: list[str]) -> None:
    spinning(tmp_path / "spin.npz", name, **kwargs)
    with pytest.raises(RecordingError) as err:
        read_recording(tmp_path / "spin.npz")
    message = str(err.value)
    assert "\n" not in message and f"column '{name}' reaches" in message
    for part in expected:
        assert part in message


def test_multi_joint_scales_apply_to_every_joint_unless_overridden(tmp_path: Path) -> None:
    header = "t,u1,q1,theta1,u2,q2,theta2"
    rows = [[repr(i * DT), 1.0, 1.0, 1.0, 1.0, 1.0, 1.0] for i in range(N)]
    path = tmp_path / "multi.csv"
    path.write_text(csv_text(header, rows))
    multi = read_recording(path, scales={"theta": DEG, "theta2": 2.0, "u": 3.0})
    assert isinstance(multi, MultiRecording)
    assert multi.joint(1).theta[0] == DEG and multi.joint(2).theta[0] == 2.0
    assert multi.joint(1).u[0] == multi.joint(2).u[0] == 3.0


def test_k_m_turns_current_into_torque(tmp_path: Path) -> None:
    rec = make_recording()
    path = tmp_path / "current.csv"
    write_recording(path, rec)
    back = read_recording(path, k_m=0.05)
    np.testing.assert_array_equal(back.u, rec.u * 0.05)
    np.testing.assert_array_equal(back.tau, rec.tau)  # only u is a current
    assert back.meta["k_m"] == 0.05
    with pytest.raises(RecordingError, match="k_m must be finite and positive"):
        read_recording(path, k_m=-1.0)


def test_parse_column_map_and_scales() -> None:
    assert parse_column_map("t=time,u=vir,q=qm,theta=qm") == {"t": "time", "u": "vir", "q": "qm", "theta": "qm"}
    assert parse_scales("q=deg, theta=DEG, u=2.5, t=1e-3") == {"q": DEG, "theta": DEG, "u": 2.5, "t": 1e-3}
    assert parse_scales("theta2=deg") == {"theta2": DEG}


def test_the_api_takes_the_scales_the_command_line_does(tmp_path) -> None:
    """``read_recording(scales={"theta": "deg"})``: the word the option documents, not only a number."""
    rec = make_recording()
    path = tmp_path / "rec.npz"
    np.savez(path, t=rec.t, u=rec.u, q=rec.q, theta=np.degrees(rec.theta))
    assert np.allclose(read_recording(path, scales={"theta": "deg"}).theta, rec.theta)


@pytest.mark.parametrize(
    ("parse", "text", "expected"),
    [
        (parse_column_map, "", "empty"),
        (parse_column_map, "t=time,u", "'u' is not of the form name=value"),
        (parse_column_map, "t=time,t=x", "'t' is given twice"),
        (parse_column_map, "speed=v", "unknown signal name(s) 'speed'; allowed: t, u, q, theta, tau"),
        (parse_column_map, "u=", "not of the form"),
        (parse_scales, "q=degrees", "must be a number or 'deg'"),
        (parse_scales, "q=0", "finite and non-zero"),
        (parse_scales, "q=nan", "finite and non-zero"),
        (parse_scales, "q0=2", "unknown signal name(s) 'q0'"),
    ],
)
def test_option_parse_errors(parse, text: str, expected: str) -> None:
    with pytest.raises(RecordingError) as err:
        parse(text)
    assert expected in str(err.value)
    assert "\n" not in str(err.value)


# --- the Recording object --------------------------------------------------------------


def test_recording_properties_and_immutability() -> None:
    rec = make_recording()
    assert rec.n == N
    assert rec.dt == pytest.approx(DT)
    assert rec.duration == pytest.approx((N - 1) * DT)
    assert list(rec.signals()) == ["t", "u", "q", "theta", "tau"]
    with pytest.raises(ValueError):
        rec.u[0] = 1.0  # arrays are read-only
    with pytest.raises(dataclasses.FrozenInstanceError):
        rec.u = np.zeros(N)
    with pytest.raises(ValueError, match="theta has 3 samples"):
        Recording(t=np.arange(4.0), u=np.zeros(4), q=np.zeros(4), theta=np.zeros(3))
    with pytest.raises(ValueError, match="gear_ratio"):
        dataclasses.replace(rec, gear_ratio=0.0)


def test_with_columns_replaces_and_checks() -> None:
    rec = make_recording()
    new = rec.with_columns(u=np.ones(N), tau=None)
    np.testing.assert_array_equal(new.u, np.ones(N))
    assert new.tau is None and list(new.signals()) == ["t", "u", "q", "theta"]
    np.testing.assert_array_equal(new.q, rec.q)
    with pytest.raises(ValueError, match="unknown column"):
        rec.with_columns(speed=np.ones(N))
    with pytest.raises(ValueError, match="samples"):
        rec.with_columns(u=np.ones(N + 1))


def test_split_is_contiguous_by_time() -> None:
    rec = make_recording(n=100)
    train, held = rec.split(0.7)
    assert (train.n, held.n) == (70, 30)
    assert train.t[-1] < held.t[0]
    np.testing.assert_array_equal(np.concatenate([train.q, held.q]), rec.q)
    assert train.gear_ratio == held.gear_ratio == rec.gear_ratio
    for bad in (0.0, 1.0, -0.5):
        with pytest.raises(ValueError, match="fraction"):
            rec.split(bad)


def test_slice_keeps_both_ends() -> None:
    rec = make_recording(n=100)
    part = rec.slice(0.010, 0.020)
    assert part.n == 11
    assert part.t[0] == rec.t[10] and part.t[-1] == rec.t[20]
    np.testing.assert_array_equal(part.tau, rec.tau[10:21])
    with pytest.raises(ValueError, match="no samples"):
        rec.slice(5.0, 6.0)


def test_multi_recording_split_and_slice() -> None:
    multi = MultiRecording((make_recording(n=100, seed=1), make_recording(n=100, seed=2)))
    train, held = multi.split(0.5)
    assert train.n + held.n == 100 and train.n_joints == 2
    np.testing.assert_array_equal(held.joint(2).u, multi.joint(2).u[train.n :])
    assert multi.slice(0.0, 0.0095).n == 10
    with pytest.raises(ValueError, match="share the same t"):
        MultiRecording((make_recording(n=100), make_recording(n=99)))


# --- bad files ---------------------------------------------------------------------------

HEADER = "t,u,q,theta,tau"


def rows_with(i: int, column: int, value: object, n: int = 20) -> list[list[object]]:
    rows = valid_rows(n)
    rows[i][column] = value
    return rows


def time_rows(times: list[float]) -> list[list[object]]:
    return [[repr(t), 0.0, 0.0, 0.0, 0.0] for t in times]


BAD_CSV: dict[str, tuple[str | bytes, list[str]]] = {
    "truncated last line": (csv_text(HEADER, valid_rows()) + "0.02,0.1,0.", ["line 22", "truncated"]),
    "wrong header": (csv_text("time,u,q,theta,tau", valid_rows()), ["missing required column(s) t", "'time'"]),
    "text in numeric column": (csv_text(HEADER, rows_with(4, 2, "abc")), ["line 6", "column 'q'", "'abc' is not a number"]),
    "empty field": (csv_text(HEADER, rows_with(4, 3, "")), ["line 6", "column 'theta'", "'' is not a number"]),
    "nan": (csv_text(HEADER, rows_with(3, 3, "nan")), ["'theta'", "nan", "sample 3 (line 5)", "--allow-gaps"]),
    "inf": (csv_text(HEADER, rows_with(7, 1, "-inf")), ["'u'", "-inf", "sample 7"]),
    "an angle infinite throughout": (csv_text(HEADER, [r[:2] + ["inf"] + r[3:] for r in valid_rows()]), ["'q'", "inf", "sample 0"]),
    # the same time with other values (a row repeated whole is dropped: test_repeated_rows_are_dropped)
    "duplicated time": (csv_text(HEADER, time_rows([0.001 * i for i in range(9)]) + [[repr(0.008), 1.0, 0.0, 0.0, 0.0]]
                                 + time_rows([0.01, 0.011])), ["duplicated", "sample 9", "t=0.008"]),
    "decreasing time": (csv_text(HEADER, time_rows([0.001 * i for i in range(9)] + [0.005, 0.01, 0.011])), ["decreasing", "sample 9"]),
    "empty file": ("", ["empty file"]),
    "blank lines only": ("\n  \n\n", ["empty file"]),
    "header only": (HEADER + "\n", ["header but no data rows"]),
    "a joint number no joint has": (csv_text("t" + "".join(f",{s}{'9' * 20}" for s in ("u", "q", "theta", "tau")),
                                             valid_rows()),
                                    ["missing required column(s) u, q, theta"]),
    "no header": (csv_text("0.0,1,2,3,4", valid_rows()), ["no header"]),
    "too few samples": (csv_text(HEADER, valid_rows(5)), ["only 5 samples", "at least 10"]),
    "theta in counts": (csv_text(HEADER, rows_with(12, 3, 40960.0)), ["'theta'", "40960", "sample 12", "--scales theta=deg"]),
    "huge torque": (csv_text(HEADER, rows_with(2, 1, 3e7)), ["'u'", "3e+07", "wrong units"]),
    "huge q": (csv_text(HEADER, rows_with(2, 2, -2e6)), ["'q'", "jumps by 2e+06 at sample 3 (line 5)", "degrees or counts", "q=deg"]),
    "huge tau": (csv_text(HEADER, rows_with(2, 4, 2e6)), ["'tau'"]),
    "gap in time": (csv_text(HEADER, time_rows([0.001 * i for i in range(10)] + [0.1 + 0.001 * i for i in range(10)])), ["gap in time", "sample 10", "t=0.009"]),
    "time in milliseconds": (csv_text(HEADER, time_rows([2.0 * i for i in range(12)])), ["sample period 2 s", "seconds"]),
    # 1 kHz with t in ms reads as 1 Hz for 11 s (10 000 s for a 10 s recording)
    "time in milliseconds at 1 kHz": (csv_text(HEADER, time_rows([1.0 * i for i in range(12)])),
                                      ["t looks like milliseconds", "1000 Hz over 0.011 s", "--scales t=0.001"]),
    "time in microseconds": (csv_text(HEADER, time_rows([500.0 * i for i in range(12)])),
                             ["t looks like microseconds", "2000 Hz", "--scales t=1e-06"]),
    "time in nanoseconds": (csv_text(HEADER, time_rows([1e-9 * i for i in range(12)])), ["sample period 1e-09 s"]),
    "unknown column": (csv_text(HEADER + ",foo", [r + [1] for r in valid_rows()]), ["unknown column(s) 'foo'", "allowed: t, u, q, theta, tau"]),
    "duplicated column": (csv_text("t,u,q,theta,q", valid_rows()), ["duplicated column name(s) 'q'"]),
    "empty column name": (csv_text("t,u,,theta,tau", valid_rows()), ["header field 3 is empty"]),
    "mixed layouts": (csv_text("t,u,q,theta,u2", valid_rows()), ["mixes single-joint names"]),
    "joint numbering gap": (csv_text("t,u2,q2,theta2,tau2", valid_rows()), ["numbered 1, 2"]),
    "not utf-8": (csv_text(HEADER, valid_rows()).encode() + b"\xff\xfe\n", ["not UTF-8"]),
    "nul byte": (csv_text(HEADER, valid_rows()).encode() + b"1,\x00\n", ["line 22"]),
}


def test_time_in_milliseconds_reads_with_the_scale_the_message_names(tmp_path: Path) -> None:
    path = tmp_path / "ms.csv"
    path.write_text(csv_text(HEADER, time_rows([1.0 * i for i in range(12)])))
    rec = read_recording(path, scales={"t": 1e-3})
    assert np.allclose(np.diff(rec.t), 1e-3)


def refusal(path: Path) -> str:
    """The message ``read_recording`` refuses ``path`` with: no warning printed before it (the
    one line is all the user sees) and the file left as it was."""
    before = (path.read_bytes(), path.stat().st_mtime_ns)
    with pytest.raises(RecordingError) as err, warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        read_recording(path)
    assert (path.read_bytes(), path.stat().st_mtime_ns) == before
    return str(err.value)


@pytest.mark.parametrize("case", list(BAD_CSV))
def test_bad_csv_is_rejected_with_one_line_and_untouched(tmp_path: Path, case: str) -> None:
    content, expected = BAD_CSV[case]
    path = tmp_path / "bad.csv"
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    message = refusal(path)
    assert "\n" not in message and "\r" not in message
    assert message.startswith(f"{path}: ")
    for part in expected:
        assert part in message, (part, message)


BAD_JSON = {
    "an integer beyond every float": ('[{"t": 0, "u": 0, "q": 1' + "0" * 400 + ', "theta": 0}'
                                      + "".join(f', {{"t": {k / 1000}, "u": 0, "q": 0, "theta": 0}}' for k in range(1, 20))
                                      + "]", "column 'q' has inf at sample 0"),
    "nested past the reader's depth": ("[" * 100_000 + "]" * 100_000, "nested deeper than a recording is"),
}


@pytest.mark.parametrize("case", list(BAD_JSON))
def test_bad_json_is_rejected_with_one_line(tmp_path: Path, case: str) -> None:
    content, expected = BAD_JSON[case]
    path = tmp_path / "bad.json"
    path.write_text(content)
    message = refusal(path)
    assert "\n" not in message and message.startswith(f"{path}: ") and expected in message


def test_a_bad_json_lines_record_is_named_by_its_line(tmp_path: Path) -> None:
    path = tmp_path / "log.jsonl"
    path.write_text("".join(f'{{"t": {k / 1000}, "u": 0, "q": 0, "theta": 0}}\n' for k in range(500)) + "{x\n")
    assert "line 501: Expecting property name" in refusal(path)


def test_missing_file_and_unknown_suffix(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="no such file"):
        read_recording(tmp_path / "nope.csv")
    other = tmp_path / "rec.xlsx"
    other.write_text("t,u,q,theta\n")
    with pytest.raises(RecordingError, match="unsupported file type '.xlsx'"):
        read_recording(other)
    with pytest.raises(RecordingError, match="not a regular file"):
        read_recording(tmp_path)


@pytest.mark.parametrize("suffix", [".mat", ".npz"])
def test_corrupt_container_is_rejected(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"bad{suffix}"
    path.write_bytes(b"PK\x03\x04 definitely not a real archive" * 10)
    message = refusal(path)
    assert "\n" not in message and "not a readable" in message


@pytest.mark.parametrize(
    ("header", "expected"),
    [
        (b"MATLAB 7.3 MAT-file".ljust(124) + b"\x00\x02IM", "not a readable MATLAB v7.3 (HDF5) file"),
        (b"MATLAB 5.0 MAT-file".ljust(124) + b"\x00\x01XX", "no MAT v5 or v7.3 header"),
        (b"MATLAB 5.0", "shorter than the 128-byte MAT header"),
    ],
)
def test_mat_header_problems(tmp_path: Path, header: bytes, expected: str) -> None:
    path = tmp_path / "rec.mat"
    path.write_bytes(header + bytes(64))
    with pytest.raises(RecordingError, match=re.escape(expected)):
        read_recording(path)


def test_npz_length_mismatch_names_the_column(tmp_path: Path) -> None:
    path = tmp_path / "rec.npz"
    np.savez(path, t=np.arange(N) * DT, u=np.zeros(N - 1), q=np.zeros(N), theta=np.zeros(N))
    with pytest.raises(RecordingError, match="column 'u' has 49 samples but 't' has 50"):
        read_recording(path)


def test_accepted_oddities(tmp_path: Path) -> None:
    """Jitter below half a period, extra columns when allowed (even text), BOM, blank lines."""
    rng = np.random.default_rng(3)
    times = np.arange(N) * DT + rng.uniform(-0.2, 0.2, N) * DT
    rows = [[repr(float(t)), 0.0, 0.0, 0.0, "ok"] for t in times]
    path = tmp_path / "odd.csv"
    path.write_bytes(b"\xef\xbb\xbf" + csv_text("t,u,q,theta,status", rows).replace("\n", "\n\n", 3).encode())
    with pytest.raises(RecordingError, match="unknown column"):
        read_recording(path)
    rec = read_recording(path, allow_extra=True)
    np.testing.assert_allclose(rec.t, times[0] + np.arange(rec.n) * DT, rtol=0, atol=1e-15)
    assert rec.meta["resampled"]["method"] == "linear interpolation"
    # Naming the columns to use leaves the others out, and says so.
    picked = read_recording(path, columns={"t": "t", "u": "u", "q": "q", "theta": "theta"})
    np.testing.assert_array_equal(picked.q, rec.q)
    assert any("left out: 'status'" in note for note in reading_notes(picked.meta))


def test_mapped_column_missing_from_csv(tmp_path: Path) -> None:
    path = tmp_path / "rec.csv"
    write_recording(path, make_recording())
    with pytest.raises(RecordingError, match=r"column 'volts' \(for u\) not found; header has 't', 'u'"):
        read_recording(path, columns={"u": "volts"})
    with pytest.raises(RecordingError, match="scale is given for 'tau2'"):
        read_recording(path, scales={"tau2": 2.0})


# --- fuzz --------------------------------------------------------------------------------

VALID_CSV = csv_text(HEADER, valid_rows(12)).encode()

# Mostly bytes that mean something in a CSV of numbers, so that mutations reach past the decoder.
chunk = st.one_of(
    st.text(alphabet="0123456789.,-+eE \n\r\"tnaifx", min_size=1, max_size=3).map(str.encode),
    st.sampled_from([b"nan", b"inf", b"1e308", b"\x00", b"\xef\xbb\xbf", b",,"]),
    st.binary(min_size=1, max_size=3),
)
mutation = st.tuples(st.sampled_from(["set", "insert", "delete"]), st.integers(0, len(VALID_CSV) - 1), chunk)


def mutate(data: bytes, edits: list[tuple[str, int, bytes]]) -> bytes:
    for op, pos, chunk in edits:
        pos = min(pos, len(data))
        if op == "set":
            data = data[:pos] + chunk + data[pos + len(chunk) :]
        elif op == "insert":
            data = data[:pos] + chunk + data[pos:]
        else:
            data = data[:pos] + data[pos + len(chunk) :]
    return data


@settings(max_examples=300, deadline=None)
@given(edits=st.lists(mutation, min_size=1, max_size=4))
def test_mutated_csv_reads_or_raises_recording_error(edits: list[tuple[str, int, bytes]]) -> None:
    data = mutate(VALID_CSV, edits)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.csv"
        path.write_bytes(data)
        try:
            rec = read_recording(path)
        except RecordingError as err:
            assert "\n" not in str(err) and str(err).startswith(str(path))
        else:
            assert rec.n >= 10 and all(np.isfinite(x).all() for x in rec.signals().values())
        assert path.read_bytes() == data


def _valid_mat() -> bytes:
    t = np.arange(12) * DT
    buf = io.BytesIO()
    scipy.io.savemat(
        buf,
        {
            "t": t, "u": t, "q": t[None, :], "theta": np.vstack([t, t]),
            "name": "axis", "cfg": {"kp": 2.0, "tag": "a"}, "parts": np.array([t[:2], "ab"], dtype=object),
            "z": np.array([1 + 2j]), "sp": scipy.sparse.csc_matrix(np.eye(2)),
        },
    )
    return buf.getvalue()


VALID_MAT = _valid_mat()
# Type codes, class numbers and sizes are where a corrupt MAT file used to crash scipy's reader.
mat_byte = st.one_of(st.integers(0, 255), st.sampled_from([0, 1, 5, 6, 8, 10, 11, 14, 15, 19, 20, 255]))


@settings(max_examples=200, deadline=None)
@given(edits=st.lists(st.tuples(st.integers(0, len(VALID_MAT) - 1), mat_byte), min_size=1, max_size=4))
def test_mutated_mat_reads_or_raises_recording_error(edits: list[tuple[int, int]]) -> None:
    data = bytearray(VALID_MAT)
    for pos, value in edits:
        data[pos] = value
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.mat"
        path.write_bytes(data)
        try:
            read_recording(path, columns={"theta": "theta[1]"})
        except RecordingError as err:
            assert "\n" not in str(err)
