"""Derived signals: --columns sources that are expressions of a file's values (recordings.derived)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mjjoint.recordings import RecordingError, parse_column_map, read_recording

N = 400
DT = 5e-3


def _servo_log(path: Path, kp: float = 400.0, vin: float = 7.4) -> dict[str, np.ndarray]:
    """A servo log as robots write them: records of goal, position and torque enable beside the
    controller's gain and the supply as scalars; returns the arrays written."""
    t = np.arange(N) * DT
    goal = 0.8 * np.sin(2 * np.pi * 0.7 * t)
    position = 0.7 * np.sin(2 * np.pi * 0.7 * t - 0.3)
    enable = (t < 1.5).astype(float)
    entries = [{"timestamp": float(a), "goal_position": float(g), "position": float(p), "torque_enable": bool(e)}
               for a, g, p, e in zip(t, goal, position, enable)]
    path.write_text(json.dumps({"kp": kp, "vin": vin, "entries": entries}))
    return {"t": t, "goal": goal, "position": position, "enable": enable}


SERVO = ("t=entries.timestamp, theta=entries.position, q=288.35*entries.position, "
         "u=0.338/2.3/288.35*entries.torque_enable*(vin*clip(kp*4096/(2*pi)/(256*885)*(entries.goal_position - "
         "entries.position), -1, 1) - 0.338*ddt(entries.position))")


def test_a_servo_logs_firmware_law_maps_goal_and_position_to_the_motor_torque(tmp_path: Path) -> None:
    """The motor torque a position servo's firmware applies, computed from its log by the
    expression: equal to the same law written in NumPy, the log's scalars as constants."""
    path = tmp_path / "servo.json"
    x = _servo_log(path)
    rec = read_recording(path, columns=parse_column_map(SERVO), gear_ratio=288.35)
    speed = 0.7 * 2 * np.pi * 0.7 * np.cos(2 * np.pi * 0.7 * x["t"] - 0.3)
    duty = np.clip(400.0 * 4096 / (2 * np.pi) / (256 * 885) * (x["goal"] - x["position"]), -1, 1)
    u = 0.338 / 2.3 / 288.35 * x["enable"] * (7.4 * duty - 0.338 * speed)
    inner = slice(10, -10)  # the derivative's ends are one-sided fits
    assert np.max(np.abs(rec.u - u)[inner]) < 1e-4 * np.max(np.abs(u))
    np.testing.assert_array_equal(rec.q, 288.35 * x["position"])
    np.testing.assert_array_equal(rec.theta, x["position"])
    assert np.all(rec.u[x["enable"] == 0] == 0)


def test_ddt_is_the_time_derivative_and_its_window_is_settable(tmp_path: Path) -> None:
    t = np.arange(N) * DT
    path = tmp_path / "r.csv"
    path.write_text("time,x\n" + "".join(f"{a:.17g},{np.sin(3 * a):.17g}\n" for a in t))
    cols = {"t": "time", "u": "ddt(x)", "q": "ddt(x, 11)", "theta": "x"}
    rec = read_recording(path, columns=cols)
    for got in (rec.u, rec.q):
        np.testing.assert_allclose(got[10:-10], 3 * np.cos(3 * t[10:-10]), atol=1e-5)
    assert not np.array_equal(rec.u, rec.q)  # the wider window is a different filter


def test_ddt_of_a_rest_is_exactly_zero_so_its_sign_is_too(tmp_path: Path) -> None:
    # A held encoder count, far from zero: the filter's rounding there has a sign of its own.
    x = np.r_[np.linspace(0.0, 1.0, N // 2), np.full(N - N // 2, 1.0)] + 123.456
    path = tmp_path / "r.csv"
    path.write_text("time,x\n" + "".join(f"{a:.17g},{b:.17g}\n" for a, b in zip(np.arange(N) * DT, x)))
    rec = read_recording(path, columns={"t": "time", "u": "sign(ddt(x))", "q": "ddt(x)", "theta": "x"})
    rest = slice(N // 2 + 10, N)
    assert np.all(rec.q[rest] == 0.0) and np.all(rec.u[rest] == 0.0)
    assert np.all(rec.u[10:N // 2 - 10] == 1.0)


def test_expressions_reach_matrix_columns_struct_fields_and_comparisons(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    data = rng.normal(size=(N, 3))
    path = tmp_path / "r.mat"
    scipy.io.savemat(path, {"data": data, "rec": {"t": np.arange(N) * DT, "gain": 2.5}})
    cols = {"t": "rec.t", "u": "rec.gain*data[:, 0] + (data[:, 1] > 0)", "q": "-data[:, 1]**2",
            "theta": "atan2(data[:, 2], 1) / 100"}
    rec = read_recording(path, columns=cols)
    np.testing.assert_allclose(rec.u, 2.5 * data[:, 0] + (data[:, 1] > 0))
    np.testing.assert_allclose(rec.q, -data[:, 1] ** 2)
    np.testing.assert_allclose(rec.theta, np.arctan2(data[:, 2], 1) / 100)


def test_a_text_tables_columns_read_by_an_expression_are_used_not_left_out(tmp_path: Path) -> None:
    path = tmp_path / "r.csv"
    t = np.arange(N) * DT
    path.write_text("time,cur,qm,ql\n" + "".join(f"{a:.17g},{np.sin(a):.17g},{np.cos(a):.17g},{0.01 * np.cos(a):.17g}\n" for a in t))
    rec = read_recording(path, columns={"t": "time", "u": "0.25*cur", "q": "qm", "theta": "ql"})
    assert rec.meta["left_out"] is None
    np.testing.assert_allclose(rec.u, 0.25 * np.sin(t))


def test_the_columns_option_keeps_an_expressions_commas_in_one_item() -> None:
    cols = parse_column_map("t=time, u=clip(cur, -1, 1)*max(a, b), q=data[:, 3], theta=ql")
    assert cols == {"t": "time", "u": "clip(cur, -1, 1)*max(a, b)", "q": "data[:, 3]", "theta": "ql"}


@pytest.mark.parametrize("u, message", [
    ("__import__('os').getcwd()", "is not allowed in an expression"),
    ("cur.real()", "is not allowed in an expression"),
    ("sinh(cur)", "is not allowed in an expression"),
    ("clip(cur, 1)", "clip takes 3 argument(s), got 2"),
    ("2*pi", "is a constant, not a signal"),
    ("ddt(cur, 4)", "ddt's window must be an odd whole number"),
    ("cur + nope", "'nope'"),
    ("cur if cur else 0", "is not allowed in an expression"),
])
def test_a_bad_expression_is_refused_in_one_line_naming_the_part(tmp_path: Path, u: str, message: str) -> None:
    path = tmp_path / "r.csv"
    path.write_text("time,cur,qm,ql\n" + "".join(f"{i * DT!r},{i},{2 * i},{0.01 * i}\n" for i in range(N)))
    with pytest.raises(RecordingError) as err:
        read_recording(path, columns={"t": "time", "u": u, "q": "qm", "theta": "ql"})
    text = str(err.value)
    assert message in text and "\n" not in text and str(path) in text


def test_ddt_refuses_uneven_samples_and_a_derivative_in_time_itself(tmp_path: Path) -> None:
    t = np.cumsum(np.where(np.arange(N) % 2, 1.3, 0.7)) * DT
    path = tmp_path / "r.csv"
    path.write_text("time,x\n" + "".join(f"{a:.17g},{np.sin(a):.17g}\n" for a in t))
    with pytest.raises(RecordingError, match="evenly spaced samples"):
        read_recording(path, columns={"t": "time", "u": "ddt(x)", "q": "x", "theta": "x"})
    with pytest.raises(RecordingError, match="ddt cannot be used in t itself"):
        read_recording(path, columns={"t": "time + ddt(x)", "u": "x", "q": "x", "theta": "x"})


# Pieces an expression is made of, and a few that must be refused, so that random sequences of
# them reach the evaluator rather than stop at the parser.
_PIECES = st.sampled_from(["cur", "qm", "ql", "time", "kp", "2", "0", "1e308", "-", "+", "*", "/", "**", "(", ")",
                           ",", "clip(", "ddt(", "min(", "sqrt(", "log(", "atan2(", "pi", ">", "<=", "[:, 0]",
                           ".x", "__class__", "lambda", "'s'", "[", "]", " "])


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(_PIECES, min_size=1, max_size=12))
def test_any_expression_reads_or_is_refused_in_one_line(tmp_path_factory, pieces) -> None:
    """No expression, however malformed, escapes as anything but a one-line RecordingError."""
    path = tmp_path_factory.getbasetemp() / "fuzz.csv"
    if not path.exists():
        path.write_text("time,cur,qm,ql\n" + "".join(f"{i * DT!r},{np.sin(i / 9):.17g},{i / 7:.17g},{i / 700:.17g}\n"
                                                    for i in range(N)))
    try:
        rec = read_recording(path, columns={"t": "time", "u": "".join(pieces), "q": "qm", "theta": "ql"},
                             allow_extra=True)
    except RecordingError as exc:
        assert "\n" not in str(exc)
    else:
        assert rec.u.shape == rec.t.shape and np.all(np.isfinite(rec.u))
