"""How identification fits the link's inertia (``ArmSpec.link_parameter``, identify/effects.py).

An arm with a tip mass fits the tip mass, which moves the link inertia both ways; a hub term can
only add to the nominal link, so a payload lighter than nominal was out of reach.
"""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjjoint.assets import ArmSpec
from mjjoint.assets.drive import DriveSpec
from mjjoint.benchmark.cases import BASE, GEAR_RATIO, NOMINAL, make_case
from mjjoint.rehearse import LabProgram, record
from mjjoint.identify.effects import base_params
from mjjoint.identify.fit import fit
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import Recording
from mjjoint.sim import joint_indices


def test_each_plant_fits_one_link_inertia_parameter():
    names = lambda plant: [p.name for p in base_params(plant)]  # noqa: E731
    assert names(ArmSpec()) == ["inertia.motor", "mass.tip"]
    assert names(ArmSpec(tip_mass=0.0)) == ["inertia.motor", "inertia.link"]
    assert names(DriveSpec()) == ["inertia.motor"]


def _link_inertia(mass: float) -> float:
    model = Structure.create(("linear_stiffness",), NOMINAL, GEAR_RATIO, {"mass.tip": mass}).compile()
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, d, full)
    ji = joint_indices(model)[0]
    return float(full[ji.link_dof, ji.link_dof])


def test_the_tip_mass_sets_the_simulated_link_inertia():
    m0 = NOMINAL.tip_mass
    nominal = _link_inertia(m0)
    assert nominal == pytest.approx(NOMINAL.link_inertia, rel=0.01)  # the sum: hub, rod, point tip
    for ratio in (0.8, 1.3):  # below and above nominal: a point mass at the rod end (the ball's
        # own inertia, 0.4 m r^2, is 0.2 % of m l^2)
        change = _link_inertia(ratio * m0) - nominal
        assert change == pytest.approx((ratio - 1) * m0 * NOMINAL.rod_length ** 2, rel=0.005)


def test_a_payload_lighter_than_nominal_is_recovered():
    truth = make_case("none", 1).truth
    truth = truth.with_values({"mass.tip": 0.85 * NOMINAL.tip_mass})
    cols = record(*truth.model_params(), LabProgram(duration=8.0, seed=1))
    rec = Recording(t=cols["t"], u=cols["u"], q=cols["q"], theta=cols["theta"], tau=cols["tau"])
    predictor = Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(seed=1))
    res = fit(predictor, Structure.create(BASE, NOMINAL, GEAR_RATIO))
    v = res.structure.values
    assert v["mass.tip"] == pytest.approx(truth.values["mass.tip"], rel=0.02)
    assert v["linear_stiffness.k1"] == pytest.approx(truth.values["linear_stiffness.k1"], rel=0.02)
    assert v["gravity.g"] == pytest.approx(9.81, rel=0.02)
