"""The flexible link's two properties, its bending stiffness and its own damping, are
identifiable from a lab recording: a rod whose damping is fixed at a guess leaves its mode's
decay to be taken up by whatever other dissipation a later candidate brings."""
from __future__ import annotations

import pytest

from mjjoint.benchmark.cases import GEAR_RATIO, make_case
from mjjoint.identify.effects import ROD_BETA
from mjjoint.identify.fit import fit
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import Recording
from mjjoint.rehearse import LabProgram, record


@pytest.mark.parametrize("beta", [3e-5, 6e-4])
def test_a_rods_stiffness_and_damping_are_recovered(beta):
    truth = make_case("none", 0).truth.with_effect(
        "link_flexibility", {"link_flexibility.ei": 300.0, "link_flexibility.beta": beta})
    cols = record(*truth.model_params(), LabProgram(duration=6.0, seed=0))
    rec = Recording(t=cols["t"], u=cols["u"], q=cols["q"], theta=cols["theta"], tau=cols["tau"])
    predictor = Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(seed=0))
    start = truth.with_values({"link_flexibility.ei": 500.0, "link_flexibility.beta": ROD_BETA})
    v = fit(predictor, start).structure.values
    assert v["link_flexibility.ei"] == pytest.approx(300.0, rel=0.05)
    assert v["link_flexibility.beta"] == pytest.approx(beta, rel=0.1)


def test_a_rod_of_negligible_damping_is_an_estimate_not_a_stand_in():
    """beta's lower bound is a rod that still bends, barely damped: a fit there is no stand-in;
    every other bound, EI's too, still marks one (``FitResult.on_bound``)."""
    s = make_case("none", 0).truth.with_effect("link_flexibility")
    names = ["link_flexibility.ei", "link_flexibility.beta"]
    lo, hi = s.bounds(names)
    assert s.stand_in_bounds(names, lo) == ("link_flexibility.ei",)
    assert s.stand_in_bounds(names, hi) == tuple(names)
    assert s.stand_in_bounds(names, (lo + hi) / 2) == ()
