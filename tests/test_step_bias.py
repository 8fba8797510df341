"""A fitted parameter's discretisation bias (``identify.fit.step_bias``): the model's step moves a
well-determined estimate by more than the noise does, so a noise interval alone misses physics
that has no step; ``check_intervals`` widens the interval by the bias its fit at half the step
shows (docs/diagnosis.md, "Intervals: coverage measured")."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from mjjoint.benchmark.cases import GEAR_RATIO, make_case
from mjjoint.benchmark.score import write_case_recording
from mjjoint.identify.effect import Param
from mjjoint.identify import fit as fit_module
from mjjoint.identify.fit import STEP_BIASED, _at_fit, _step_biased, check_intervals, fit, jacobian, widened
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import read_recording


def test_an_interval_is_joined_with_itself_moved_by_the_bias():
    lin, log = Param("a.x", 1.0, -10.0, 10.0, log=False), Param("b.y", 1.0, 1e-3, 1e3)
    structure = SimpleNamespace(params=[lin, log])
    at = SimpleNamespace(names=["a.x", "b.y"], optimum=SimpleNamespace(x=np.array([1.0, 0.0])))
    spans = {"a.x": (0.9, 1.1), "b.y": (0.5, 2.0)}
    out, warnings = widened(structure, at, ["a.x", "b.y"], np.array([0.3, -math.log(4.0)]), spans, [],
                            _step_biased)
    assert out["a.x"] == pytest.approx((0.9, 1.4))          # the upper end moved by the shift
    assert out["b.y"] == pytest.approx((0.125, 2.0))         # the lower end, in the log coordinate
    assert len(warnings) == 2 and "a.x = 1" in warnings[0]   # both shifts beyond their half-widths
    small, quiet = widened(structure, at, ["a.x"], np.array([0.05, 0.0]), spans, [], _step_biased)
    assert small["a.x"] == pytest.approx((0.9, 1.15)) and not quiet  # within the noise: widened, no warning


def test_a_hysteretic_gears_interval_holds_the_truth_recorded_at_half_the_step(tmp_path):
    """The concealed hysteresis case of seed 5, its truth recorded at half the model's step
    (physics nearer its converged solution): the fit explains the recording, and its elastic share
    is 0.33 % low, three times its noise interval's half-width; widened by the step's bias, the
    interval holds it."""
    case = make_case("transmission_hysteresis", 5)
    path = write_case_recording(case, tmp_path, 8.0, timestep=case.truth.nominal.timestep / 2)
    rec = read_recording(path, gear_ratio=GEAR_RATIO)
    predictor = Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(seed=5))
    start = Structure.create(case.truth.effects, case.truth.nominal, GEAR_RATIO, settings=case.truth.settings)
    result = fit(predictor, start, max_iter=30)
    name, truth = "transmission_hysteresis.mu", case.truth.values["transmission_hysteresis.mu"]
    lo, hi = result.intervals[name]
    assert not lo <= truth <= hi  # the noise interval misses physics without the model's step
    checked = check_intervals(predictor, result, [name])
    lo, hi = checked.intervals[name]
    assert lo <= truth <= hi, (lo, truth, hi)
    assert any(w.startswith(name) and STEP_BIASED in w for w in checked.warnings)


def test_the_jacobian_taken_again_for_the_check_is_the_fits_own(tmp_path, monkeypatch):
    """A fit result keeps the point its intervals' Jacobian was taken at, not the Jacobian (the
    residual's size times the parameters); the check takes it again there, the same numbers."""
    case = make_case("backlash", 0)
    path = write_case_recording(case, tmp_path, 3.0)
    predictor = Predictor(Measured.from_recording(read_recording(path, gear_ratio=GEAR_RATIO), GEAR_RATIO),
                          WindowDesign(seed=0))
    real, seen = fit_module.intervals, []

    def spy(jac, *args):
        seen.append(jac.copy())
        return real(jac, *args)
    monkeypatch.setattr(fit_module, "intervals", spy)
    start = Structure.create(case.truth.effects, case.truth.nominal, GEAR_RATIO, settings=case.truth.settings)
    result = fit(predictor, start, max_iter=5)
    at = result.at_optimum
    assert not any(isinstance(v, np.ndarray) and v.size >= seen[-1].size for v in vars(at).values())
    residual = _at_fit(predictor, result.structure, at)
    np.testing.assert_array_equal(jacobian(residual, at, residual(at.optimum.x)[:, 0]), seen[-1])
