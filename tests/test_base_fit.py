"""A diagnosis's base fit from a start its step cannot hold (``diagnosis.loop._base_fit``).

Initial values estimated from a recording can make the model too stiff for the plant's step (a
big axis recorded without its torque column: its Coulomb slope against the motor's inertia).
From there every prediction diverges, the LM cannot move, and every screen would be judged
against a base of cost 1e6. The base is fitted at the step the stability check asks for, then
carried back to the plant's step where its fitted values are stable there."""
from __future__ import annotations

import pytest

from mjjoint.benchmark.cases import GEAR_RATIO, make_case
from mjjoint.benchmark.score import write_case_recording
from mjjoint.diagnosis.loop import UNSTABLE_COST, DiagnoseOptions, _base_fit, _off_the_floor
from mjjoint.identify.fit import fit
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import read_recording


@pytest.fixture(scope="module")
def setting(tmp_path_factory):
    case = make_case("none", 0)  # the base is the truth: a fit from any start it holds finds it
    path = write_case_recording(case, tmp_path_factory.mktemp("base_fit"), 3.0)
    predictor = Predictor(Measured.from_recording(read_recording(path, gear_ratio=GEAR_RATIO), GEAR_RATIO),
                          WindowDesign(seed=0))
    return predictor, Structure.create(case.base_effects, case.truth.nominal, GEAR_RATIO), case.truth


def test_a_base_that_diverges_from_its_start_is_fitted_at_a_finer_step_then_at_the_plants(setting):
    predictor, base, truth = setting
    light = base.with_values({"inertia.motor": base.values["inertia.motor"] / 10})  # too stiff at 0.5 ms
    assert not predictor.stable(light)
    assert not fit(predictor, light).cost_test < UNSTABLE_COST  # the LM cannot leave a diverged start
    said: list[str] = []
    result = _base_fit(predictor, light, DiagnoseOptions(), said.append, None)
    assert any("prediction diverged" in line and "fitted again at timestep" in line for line in said), said
    assert result.structure.nominal.timestep == base.nominal.timestep  # carried back to the plant's step
    assert result.cost_test <= 1.05 * fit(predictor, base).cost_test  # as good as from a start it holds
    assert result.structure.values["inertia.motor"] == pytest.approx(truth.values["inertia.motor"], rel=0.05)


def test_a_base_its_step_holds_is_fitted_once(setting):
    predictor, base, _ = setting
    said: list[str] = []
    result = _base_fit(predictor, base, DiagnoseOptions(), said.append, None)
    assert not said and result.cost_test == fit(predictor, base).cost_test


def test_a_term_the_fit_ran_to_nothing_is_fitted_again_from_its_start(setting):
    """In log coordinates the gradient along a parameter vanishes at its physical floor: the
    bearing's viscous drag held there, the LM bends gravity instead and stays."""
    predictor, base, truth = setting
    held = fit(predictor, base.with_values({"load_friction.viscous": 1.05e-5}))
    assert held.structure.values["load_friction.viscous"] < 1e-4
    said: list[str] = []
    again = _off_the_floor(predictor, held, base, DiagnoseOptions(), said.append, None)
    assert any("load_friction.viscous fitted to nothing" in line and line.endswith(": kept") for line in said), said
    viscous = truth.values["load_friction.viscous"]
    assert again.structure.values["load_friction.viscous"] == pytest.approx(viscous, rel=0.1)
    assert again.cost_test <= 1.05 * fit(predictor, base).cost_test
    assert _off_the_floor(predictor, again, base, DiagnoseOptions(), said.append, None) is again
