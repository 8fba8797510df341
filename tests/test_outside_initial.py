"""A link of another size starts from the recording: tip mass, gravity and bearing friction."""
from __future__ import annotations

import dataclasses

import pytest

from mjjoint.assets import ArmSpec
from mjjoint.benchmark.independent.cases import make_case
from mjjoint.benchmark.independent.record import record
from mjjoint.identify.initial import estimate
from mjjoint.identify.windows import Measured
from mjjoint.recordings import Recording


def _measured(name: str, **over) -> tuple[Measured, object]:
    case = make_case(name, 0, duration=4.0)
    plant = dataclasses.replace(case.plant, **over)
    cols = record(plant, case.excitation, case.sensors, 0)
    rec = Recording(t=cols["t"], u=cols["u"], q=cols["q"], theta=cols["theta"], tau=cols["tau"])
    return Measured.from_recording(rec, plant.gear_ratio), plant


def test_a_big_link_starts_at_its_inertia_gravity_and_bearing_friction():
    m, plant = _measured("big_axis", backlash=0.0)   # a 20-40 kg m^2 link, the arm's is 0.18
    arm = ArmSpec(segments=0)
    v = estimate(m, arm).values
    length = arm.rod_length
    j_link = arm.hub_inertia + arm.rod_mass * length ** 2 / 3 + v["mass.tip"] * length ** 2
    assert j_link == pytest.approx(plant.link_inertia, rel=0.05)
    moment = v["gravity.g"] * (arm.rod_mass * length / 2 + v["mass.tip"] * length)
    assert moment == pytest.approx(plant.gravity_moment, rel=0.1)  # a start: 4 s of sweep
    assert v["load_friction.fc"] == pytest.approx(plant.load_coulomb, rel=0.2)


def test_a_link_of_the_nominal_size_keeps_the_catalogue_start():
    m, _ = _measured("control")
    arm = ArmSpec(segments=0)
    assert not {"mass.tip", "gravity.g", "load_friction.fc"} & set(estimate(m, arm).values)
