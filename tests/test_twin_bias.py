"""The fit's own bias (``identify.fit.twin_bias``): windows started from states reconstructed out
of the samples move an estimate systematically, which the noise intervals do not hold; the same fit repeated
on the fitted model's noisy twin of the recording (``identify.twin``) shows the move, and
``check_intervals`` widens each interval by it (docs/diagnosis.md, "Intervals: coverage measured")."""
from __future__ import annotations

import numpy as np
import pytest

from mjjoint.benchmark.cases import GEAR_RATIO, make_case
from mjjoint.benchmark.score import write_case_recording
from mjjoint.cli.fit import RESTARTS
from mjjoint.identify import fit as fit_module
from mjjoint.identify.fit import check_intervals, fit, twin_bias
from mjjoint.identify.structure import Structure
from mjjoint.identify.twin import Twin
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import read_recording

DELAY = "input_delay.delay"


@pytest.fixture(scope="module")
def dead_time(tmp_path_factory):
    """The coverage benchmark's dead-time truth of seed 16 (8 s at the model's own step), fitted as
    ``mjjoint fit`` fits: the estimate comes out ~5 us short of the truth."""
    case = make_case("input_delay", 16)
    rec = read_recording(write_case_recording(case, tmp_path_factory.mktemp("rec"), 8.0), gear_ratio=GEAR_RATIO)
    predictor = Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(seed=16))
    start = Structure.create(case.truth.effects, case.truth.nominal, GEAR_RATIO, settings=case.truth.settings)
    return predictor, fit(predictor, start, max_iter=30, restarts=RESTARTS), case.truth.values[DELAY]


def test_the_twin_shows_the_dead_times_bias_and_its_interval_then_holds_the_truth(dead_time, monkeypatch):
    predictor, result, truth = dead_time
    value = result.structure.values[DELAY]
    lo, hi = result.intervals[DELAY]
    assert not lo <= truth <= hi and value < truth  # the noise interval misses, the estimate short
    shift, rollouts = twin_bias(predictor, result, result.at_optimum)
    # On its twin the fit moves the delay short by most of what it missed the truth by.
    assert 0.5 * (truth - value) < _moved(result, shift) < 1.5 * (truth - value), (_moved(result, shift), truth - value)
    assert 0 < rollouts < 0.5 * result.rollouts
    checked = check_intervals(predictor, result, [], biased=list(result.intervals))
    lo, hi = checked.intervals[DELAY]
    assert lo <= truth <= hi, (lo, truth, hi)
    # Without the twin's widening the same check misses it: the step's bias does not hold it.
    monkeypatch.setattr(fit_module, "twin_bias", lambda *a: (None, 0.0))
    lo, hi = check_intervals(predictor, result, [], biased=list(result.intervals)).intervals[DELAY]
    assert not lo <= truth <= hi


def test_the_bias_is_the_window_starts_not_the_noise_draw(dead_time):
    # Noise and quantisation zeroed, the twin is the fitted model's own run; the fit still moves
    # the delay there by what it moves it on the noisy twin: the windows' starts, reconstructed
    # from the samples, carry the bias, so one draw of the noise measures it.
    predictor, result, _ = dead_time
    silent = {s: 0.0 for s in ("q", "theta", "delta", "tau")}
    twins = Twin(predictor, result.structure, noise=silent, quantum=silent)
    twin = twins.draw(np.random.default_rng(0))
    assert np.array_equal(twin.m.q, twins.run["q"]) and np.array_equal(twin.m.tau, twins.run["tau"])
    at = result.at_optimum
    refit = fit(twin, result.structure, at.names, max_iter=fit_module.TWIN_ITER, windows=at.windows)
    move = result.structure.values[DELAY] - refit.structure.values[DELAY]
    shift, _ = twin_bias(predictor, result, at)
    lo, hi = result.intervals[DELAY]
    assert move > 0.25 * (hi - lo) / 2  # a move of the size of the noise interval
    assert abs(_moved(result, shift) - move) < 0.2 * (hi - lo) / 2, (_moved(result, shift), move)


def _moved(result, shift) -> float:
    """The delay's shift (optimiser coordinates) in seconds."""
    at = result.at_optimum
    j = at.names.index(DELAY)
    p = next(p for p in result.structure.params if p.name == DELAY)
    return p.from_unit(at.optimum.x[j] + shift[j]) - p.from_unit(at.optimum.x[j])


def test_a_twin_unlike_the_recording_widens_nothing(dead_time, monkeypatch):
    # A free run that drifts off (an open-loop run of a closed-loop recording) says nothing about
    # the fit's windows: no shift, and the reason kept.
    predictor, result, _ = dead_time
    monkeypatch.setattr(Predictor, "spread", lambda self, s, w: 1.0 if self is predictor else 3.0)
    shift, rollouts = twin_bias(predictor, result, result.at_optimum)
    assert shift is None and rollouts == 0.0
    twins = Twin(predictor, result.structure)
    assert twins.draw(np.random.default_rng(0)) is None and "not like the recording" in twins.note


def test_mjjoint_fit_runs_the_fitted_model_free_once_for_the_intervals_and_the_floor(dead_time, monkeypatch):
    # The twin's bias and the noise floor are both drawn from the fitted model's one free run.
    from argparse import Namespace
    from types import SimpleNamespace

    from mjjoint.cli.fit import fitted
    from mjjoint.diagnosis.floor import judged

    predictor, result, _ = dead_time
    runs = []
    free_run = Predictor.free_run
    monkeypatch.setattr(Predictor, "free_run", lambda self, s: runs.append(s) or free_run(self, s))
    reported, floor = fitted(SimpleNamespace(predictor=predictor, base=result.structure),
                             Namespace(max_iter=2, restarts=0), None)
    assert len(runs) == 1 and runs[0] is reported.structure
    # The same as each part making its own.
    alone = fit_module.reported(predictor, fit(predictor, result.structure, max_iter=2, restarts=0))
    assert alone.intervals == reported.intervals
    assert judged(predictor, alone)[1].twin == floor.twin
    assert len(runs) == 3


def test_a_twin_reads_the_models_own_sensors(tmp_path):
    # A twin is recorded through the fitted model's sensor effects, as its window predictions are:
    # without them the fit on the twin walks a right gain, offset or skew back to none, and the
    # widened interval spans twice the effect.
    case = make_case("torque_gain", 0)
    rec = read_recording(write_case_recording(case, tmp_path, 2.0), gear_ratio=GEAR_RATIO)
    predictor = Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(seed=0))
    plain = Structure.create(case.base_effects, case.truth.nominal, GEAR_RATIO, dict(case.truth.values))
    sensed = Structure.create(case.base_effects + ("sensor_skew", "torque_gain", "torque_offset"),
                              case.truth.nominal, GEAR_RATIO,
                              {**case.truth.values, "sensor_skew.lag": 2e-3, "torque_gain.gain": 1.2,
                               "torque_offset.offset": 0.3})
    bare, seen = predictor.free_run(plain), predictor.free_run(sensed)
    ran = slice(int(predictor.starts[0]), None)
    assert np.allclose(seen["tau"][ran], 1.2 * bare["tau"][ran] + 0.3)
    late = int(2e-3 * predictor.m.rate)  # whole samples: the skew's shift reads the samples themselves
    # (the skewed model's run starts from states rebuilt for its skew: the same to rounding)
    assert np.allclose(seen["theta"][ran][late:], bare["theta"][ran][:-late], rtol=1e-9, atol=1e-12)
    assert np.array_equal(seen["q"], bare["q"])
