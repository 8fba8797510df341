"""Viewing: the default Rerun layouts written into the .rrd files, --spawn without a display,
and the progress of a diagnosis (round, candidate, time left)."""
from __future__ import annotations

import sys
import uuid

import pytest
from rerun.chunk import RrdReader

import mjjoint.viz.viewer as viewer
from mjjoint.cli import main
from mjjoint.diagnosis.clock import Phases, ScreenClock
from mjjoint.sim import Simulator
from mjjoint.viz.rerun_log import log_traces

HORIZONTAL, VERTICAL = 2, 3  # rerun's ContainerKind


def blueprint_tree(path):
    """The default blueprint of an .rrd as nested tuples: ("Horizontal"|"Vertical", [...]) for
    containers, (class, name, contents) for views."""
    (store,) = RrdReader(path).blueprints()
    rows = {}
    for chunk in RrdReader(path).stream(store=store):
        batch = chunk.to_record_batch()
        rows.setdefault(chunk.entity_path.lstrip("/"), {}).update(
            {n.split(":")[-1]: batch.column(n).to_pylist()[-1] for n in batch.schema.names if ":" in n})

    def node(key):
        r = rows[key]
        if key.startswith("container/"):
            kind = {HORIZONTAL: "Horizontal", VERTICAL: "Vertical"}.get(r["container_kind"][0], r["container_kind"][0])
            return kind, [node(c) for c in r["contents"]]
        return r["class_identifier"][0], r["display_name"][0], rows[f"{key}/ViewContents"]["query"]
    root = rows["viewport"]["root_container"][0]
    return node(f"container/{uuid.UUID(bytes=bytes(root))}")


def entities(path) -> set[str]:
    return {chunk.entity_path for chunk in RrdReader(path).stream()}


def test_simulate_shows_the_arm_beside_the_traces(tmp_path):
    rrd = tmp_path / "loop.rrd"
    assert main(["simulate", "--controller", "pd", "--reference", "step", "--param", "t0=0.1", "--duration", "0.5",
                 "--rrd", str(rrd)]) == 0
    kind, (arm, plots) = blueprint_tree(rrd)
    assert kind == "Horizontal" and arm[:2] == ("3D", "arm") and arm[2] == ["/world/**"]
    assert plots[0] == "Vertical" and all(v[0] == "TimeSeries" for v in plots[1])
    logged = entities(rrd)
    queried = [q for v in plots[1] for q in v[2] if not q.endswith("**")]
    assert queried and set(queried) <= logged  # every plot shows signals that are there
    assert any(e.startswith("/world/arm/") for e in logged)
    angles = next(v for v in plots[1] if v[1].startswith("q/N and theta"))
    assert {"/joint/theta", "/sensed/theta", "/sensed/theta_ref"} <= set(angles[2])  # true, sensed, reference


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("diag")
    rec = folder / "rec.csv"
    assert main(["simulate", "--controller", "pd", "--duration", "5", "--csv", str(rec)]) == 0
    capture = pytest.MonkeyPatch()
    log = folder / "stderr.txt"
    with log.open("w") as err:
        capture.setattr(sys, "stderr", err)
        try:
            code = main(["diagnose", str(rec), "--gear-ratio", "160", "--base", "coulomb_friction,linear_stiffness",
                         "--max-rounds", "2", "--candidates", "viscous_friction,load_friction", "--fit-iter", "2",
                         "--screen-iter", "1", "--out", str(folder / "out")])
        finally:
            capture.undo()
    assert code == 0
    return folder / "out", log.read_text().splitlines()


def test_a_diagnosis_shows_measured_before_after_and_the_located_residual(diagnosed):
    out, _ = diagnosed
    rrd = out / "traces.rrd"
    kind, rows = blueprint_tree(rrd)
    assert kind == "Vertical"
    *signal_rows, heldout = rows
    assert heldout[2] == ["/windows/heldout"] and len(signal_rows) == 4  # q, theta, delta, tau
    logged = entities(rrd)
    labels = {"fitted"} if "/fitted/q" in logged else {"before", "after"}
    for row_kind, (values, residual) in signal_rows:
        assert row_kind == "Horizontal"
        signal = values[2][0].rsplit("/", 1)[1]
        assert set(values[2]) == {f"/{r}/{signal}" for r in ("measured", *labels)}
        assert set(residual[2]) == {f"/residual/{r}/{signal}" for r in labels} | {f"/located/{signal}"}
        assert set(values[2]) | set(residual[2]) <= logged


def test_diagnose_reports_round_candidate_and_time_left(diagnosed):
    _, lines = diagnosed
    # each candidate's first stage, on the coarse subset, reports where the round stands; the best
    # ones are then finished on all windows (docs/diagnosis.md, the two-stage screens)
    screens = [line for line in lines if "screened" in line and "on all windows" not in line]
    finished = [line for line in lines if "screened" in line and "on all windows" in line]
    assert finished and all("held-out cost" in line for line in finished)
    assert screens and all("round 1 of 2" in line or "round 2 of 2" in line for line in screens)
    assert any("candidate 1 of 2" in line for line in screens) and any("candidate 2 of 2" in line for line in screens)
    assert all("time left ~" in line and " s this round" in line for line in screens)


def test_the_time_left_counts_the_candidates_still_to_screen():
    clock = ScreenClock(rounds=3)
    clock.record(1.0), clock.record(3.0)  # 2 s per candidate
    assert "time left ~4 s this round, ~14 s if all 3 rounds run" in clock.status(2, 4)  # 2 now, 3 + 2 later
    clock.round = 3
    assert "round 3 of 3, candidate 4 of 4; time left ~0 s this round, ~0 s" in clock.status(4, 4)


def test_phases_charge_what_runs_inside_each_to_it_alone():
    """A phase opened inside another is charged to itself only: the phases add up to the whole."""
    count = [0.0]
    phases = Phases(lambda: count[0])
    with phases("outer"):
        count[0] += 2
        with phases("inner"):
            count[0] += 5
        count[0] += 1
    with phases("inner"):
        count[0] += 3
    spent = phases.as_dict()
    assert spent["outer"]["rollouts"] == 3 and spent["outer"]["count"] == 1
    assert spent["inner"]["rollouts"] == 8 and spent["inner"]["count"] == 2
    assert "inner 8 rollouts" in phases.line() and "(2x)" in phases.line()


def test_a_diagnosis_says_where_its_rollouts_went(diagnosed):
    """Every rollout of a diagnosis is charged to one phase (diagnosis.json, ``budget.phases``, and
    the last progress line); a final robust estimate is fitted at the end only where the current
    one is not one already, nor the base's made when the search found nothing."""
    import json
    out, lines = diagnosed
    budget = json.loads((out / "diagnosis.json").read_text())["budget"]
    phases = budget["phases"]
    assert {"base fit", "locate", "screens, subset"} <= set(phases)
    assert sum(p["rollouts"] for p in phases.values()) == pytest.approx(budget["rollouts_full_length"], abs=0.1 * len(phases))
    spent = [line.split("] ", 1)[-1] for line in lines if line.split("] ", 1)[-1].startswith("spent: ")]
    assert len(spent) == 1 and all(f"{name} " in spent[0] for name in phases)
    refitted = any(line.split("] ", 1)[-1].startswith("final estimate: refitting") for line in lines)
    assert refitted == ("final robust estimate" in phases)
    assert refitted or any("already under the robust loss" in line or "final estimate: the base's" in line
                           for line in lines)


@pytest.fixture
def headless(monkeypatch):
    for name in viewer.DISPLAY_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(sys, "platform", "linux")


def test_spawn_without_a_display_writes_the_rrd_and_says_how_to_view_it(tmp_path, monkeypatch, capsys, headless):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--duration", "0.2", "--spawn"]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert "no display" in err and "rerun out/simulate/trace.rrd" in err and "on a machine with a display" in err
    assert "gRPC" not in err and "Traceback" not in err
    assert RrdReader(tmp_path / "out" / "simulate" / "trace.rrd").blueprints()


def test_a_viewer_that_cannot_start_gets_the_same_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("DISPLAY", ":1")
    monkeypatch.setattr(viewer, "VIEWER", (sys.executable, "-c", "import sys; sys.exit(3)"))
    rrd = tmp_path / "x.rrd"
    assert main(["simulate", "--duration", "0.2", "--spawn", "--rrd", str(rrd)]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exit code 3" in err and f"rerun {rrd}" in err and rrd.is_file()


def test_a_viewer_that_keeps_running_is_left_open(tmp_path, monkeypatch):
    monkeypatch.setenv("DISPLAY", ":1")
    monkeypatch.setattr(viewer, "VIEWER", (sys.executable, "-c", "import time; time.sleep(2)"))
    assert viewer.open_viewer(tmp_path / "x.rrd", wait=0.5) is None


def test_the_library_refuses_to_spawn_without_a_display(tmp_path, headless):
    sim = Simulator()
    trace = sim.run([0.0] * 10)
    with pytest.raises(OSError, match="no display"):
        log_traces(trace, spawn=True)
