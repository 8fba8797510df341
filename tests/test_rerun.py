"""Rerun logging: read the .rrd back with rerun's own reader and compare with the trace."""
from __future__ import annotations

from collections import defaultdict

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from mjjoint.excitation import Step
from mjjoint.sim import Simulator
from mjjoint.viz.rerun_log import TIMELINE, log_traces

BODIES = ("rotor", "hub", "segment1", "segment2", "segment3", "segment4", "tip")


def read_rrd(path) -> dict[str, dict[str, list]]:
    """entity path -> column name -> values (time-sorted), over all chunks of the recording."""
    rows: dict[str, list[dict]] = defaultdict(list)
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        names = [n for n in batch.schema.names if not n.startswith("rerun.controls")]
        cols = {n: _plain(batch.column(n)).to_pylist() for n in names}
        for i in range(batch.num_rows):
            rows[chunk.entity_path].append({n: cols[n][i] for n in names})
    out = {}
    for entity, rs in rows.items():
        rs.sort(key=lambda r: r.get(TIMELINE) or 0)
        out[entity] = {n: [r[n] for r in rs if r.get(n) is not None] for n in {k for r in rs for k in r}}
    return out


def _plain(column: pa.Array) -> pa.Array:
    return column.cast(pa.int64()) if pa.types.is_duration(column.type) else column  # durations as ns


@pytest.fixture(scope="module")
def step_run():
    sim = Simulator()
    trace = sim.run(Step(amplitude=0.1, t0=0.1).sample(1000, 1.5))  # swings the link ~30 deg
    return sim, trace


@pytest.fixture(scope="module")
def logged(step_run, tmp_path_factory):
    sim, trace = step_run
    path = tmp_path_factory.mktemp("rrd") / "trace.rrd"
    assert log_traces(trace, model=sim.model, recording_name="test", rrd_path=path) == path
    return read_rrd(path)


def _series(logged, entity):
    col = logged[entity]
    return np.array(col[TIMELINE]), np.array([v[0] for v in col["Scalars:scalars"]])


@pytest.mark.parametrize("name, signal", [("q", "q"), ("tau", "tau"), ("theta", "theta"), ("state/x", None),
                                          ("u", "u"), ("friction", "friction")])
def test_scalars_equal_the_trace_at_their_times(step_run, logged, name, signal):
    _, trace = step_run
    t_ns, values = _series(logged, f"/joint/{name}")
    assert len(values) == len(trace.t)
    expected = trace.state("x") if signal is None else getattr(trace, signal)
    k = t_ns // 1_000_000  # sample index at 1 kHz
    assert np.array_equal(t_ns, k * 1_000_000) and np.array_equal(k, np.arange(len(trace.t)))
    for i in (0, 137, 600, len(trace.t) - 1):
        assert values[i] == expected[k[i]]


def test_arm_bodies_follow_the_link_angle(step_run, logged):
    _, trace = step_run
    for body in BODIES:
        assert "Transform3D:translation" in logged[f"/world/arm/{body}"], body
    hub = logged["/world/arm/hub"]
    t = np.array(hub[TIMELINE]) / 1e9
    assert 60 <= len(t) <= 90 and t[-1] > 1.4  # 1.5 s decimated to ~50 Hz
    k = np.round(t * 1000).astype(int)
    theta = trace.theta[k]
    assert np.ptp(theta) > 0.3
    # The hub turns about +y by theta: quaternion (x, y, z, w) = (0, sin(theta/2), 0, cos(theta/2)).
    quat = np.array([q[0] for q in hub["Transform3D:quaternion"]])
    assert np.allclose(2 * np.arctan2(quat[:, 1], quat[:, 3]), theta, atol=1e-5)
    assert np.allclose(quat[:, [0, 2]], 0, atol=1e-6)
    # The tip hangs a rod length below the hub and swings with it (the rod bends only slightly):
    # rotating (0, 0, -L) about +y by theta gives (-L sin theta, 0, -L cos theta).
    tip = np.array([p[0] for p in logged["/world/arm/tip"]["Transform3D:translation"]])
    assert np.allclose(np.hypot(tip[:, 0], tip[:, 2]), 0.4, rtol=0.01)
    assert np.allclose(np.arctan2(-tip[:, 0], -tip[:, 2]), theta, atol=0.01)


def test_geoms_are_drawn_in_their_bodies(logged):
    tip_geoms = [e for e in logged if e.startswith("/world/arm/tip/")]
    assert len(tip_geoms) == 1
    half = logged[tip_geoms[0]]["Ellipsoids3D:half_sizes"][0][0]
    assert np.allclose(half, 0.031)  # the 1 kg tip sphere
    assert any("Capsules3D:radii" in logged[e] for e in logged if e.startswith("/world/arm/segment1/"))


def test_several_traces_get_their_own_subtrees(step_run, tmp_path):
    sim, trace = step_run
    path = tmp_path / "two.rrd"
    log_traces({"measured": trace, "simulated": trace}, model=sim.model, recording_name="two", rrd_path=path)
    logged = read_rrd(path)
    for name in ("measured", "simulated"):
        assert len(_series(logged, f"/{name}/joint/tau")[1]) == len(trace.t)
        assert f"/{name}/world/arm/tip" in logged
    assert "/joint/tau" not in logged
    assert RrdReader(path).blueprints()  # the default layout travels with the file


def test_bad_calls_fail_before_writing(step_run, tmp_path):
    sim, trace = step_run
    with pytest.raises(ValueError, match="rrd_path or spawn"):
        log_traces(trace)
    path = tmp_path / "bad.rrd"
    with pytest.raises(ValueError, match="qpos"):
        log_traces(trace, model=sim.model, qpos=trace.qpos[:, :2], rrd_path=path)
    assert not path.exists()
