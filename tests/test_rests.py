"""The rests of a recording and a model's creep through them (``diagnosis.rests``)."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from mjjoint.benchmark.cases import GEAR_RATIO, make_case as concealed_case
from mjjoint.benchmark.independent.cases import BASE, make_case
from mjjoint.benchmark.independent.record import record, write_csv
from mjjoint.benchmark.score import write_case_recording
from mjjoint.diagnosis.rests import CREEP_SHARE, MIN_SHARE, creep, rest_mask
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.problem import Inputs, load_problem
from mjjoint.recordings import read_recording


def _fitted(structure):
    return SimpleNamespace(structure=structure)  # creep reads a fit's structure alone


def test_rests_are_the_spans_where_the_encoder_holds_for_long_enough():
    """A 15-bit encoder's angle: ramps, a rest of 0.3 s, one of 0.05 s (too short) and one with
    the count flickering by one: the two long rests, and nothing of the ramps or the short stop."""
    rate, count = 1000.0, 2 * np.pi / 2**15
    t = np.arange(0.0, 2.0, 1.0 / rate)
    v = np.where((t >= 0.5) & (t < 0.8), 0.0, 1.0)          # rest 0.5-0.8 s
    v = np.where((t >= 1.2) & (t < 1.25), 0.0, v)            # too short
    v = np.where(t >= 1.6, 0.0, v)                            # rest from 1.6 s, flickering
    q = np.cumsum(v) / rate
    q[(t >= 1.6) & (np.arange(t.size) % 2 == 0)] += count
    m = SimpleNamespace(q=np.round(q / count) * count, rate=rate, per_segment=lambda f, x: f(x))
    mask = rest_mask(m)
    assert mask[(t > 0.51) & (t < 0.79)].all() and mask[t > 1.61].all()
    assert not mask[(t > 0.1) & (t < 0.45)].any() and not mask[(t > 0.85) & (t < 1.55)].any()


def test_a_model_without_a_holding_friction_creeps_through_the_rests_of_point_to_point_moves(tmp_path):
    """An independently written LuGre joint moved point to point rests a quarter of the time; the
    base at the recording's start values, its friction's sign regularised over 1 rad/s, creeps
    through those rests at about the band itself: the sign shows. The same model with the exact
    sign holds the rotor still there."""
    case = make_case("control", 0, 4.0, program="moves")
    path = write_csv(tmp_path / "moves.csv", record(case.plant, case.excitation, case.sensors, 0))
    problem = load_problem(path, Inputs(gear_ratio=case.plant.gear_ratio, base=BASE))
    creeping = creep(problem.predictor, _fitted(problem.base))
    assert creeping.share > 0.2 and creeping.speed >= CREEP_SHARE * creeping.v_eps and creeping.shown
    assert "rests in" in creeping.describe()
    held = creep(problem.predictor, _fitted(problem.base.with_effect("sticking_friction")))
    assert held.speed == 0.0 and not held.shown


def test_the_truth_itself_does_not_creep_where_its_recording_rests(tmp_path):
    """The concealed benchmark's lab programme rests a fifth of the time under its regularised
    friction: the truth's own model moves no faster there than its recording, far below the
    band, and a sweep without rests says nothing at all."""
    case = concealed_case("none", 0)
    rec = read_recording(write_case_recording(case, Path(tmp_path), 8.0), gear_ratio=GEAR_RATIO)
    predictor = Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(seed=0))
    truth = creep(predictor, _fitted(case.truth))
    assert truth.share >= MIN_SHARE and truth.speed < 0.01 * truth.v_eps and not truth.shown
    sweep = make_case("control", 0, 4.0)
    path = write_csv(tmp_path / "sweep.csv", record(sweep.plant, sweep.excitation, sweep.sensors, 0))
    problem = load_problem(path, Inputs(gear_ratio=sweep.plant.gear_ratio, base=BASE))
    found = creep(problem.predictor, _fitted(problem.base))
    assert found is None or (found.share < MIN_SHARE and not found.shown)
