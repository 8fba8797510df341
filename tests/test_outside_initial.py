"""A link of another size starts from the recording: tip mass, gravity and bearing friction."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from mjjoint.assets import ArmSpec
from mjjoint.benchmark.independent.cases import make_case
from mjjoint.benchmark.independent.record import record
from mjjoint.cli import main
from mjjoint.identify.initial import estimate
from mjjoint.identify.windows import Measured
from mjjoint.problem import Inputs, load_problem
from mjjoint.recordings import Recording

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "default.toml"


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


@pytest.fixture(scope="module")
def bending(tmp_path_factory) -> Measured:
    """The shipped arm's 4-segment rod and hysteretic gear (``examples/default.toml`` without the
    hardening spring) driven by a 10 s multisine to the gear's rated deflection."""
    folder = tmp_path_factory.mktemp("bending")
    model, rec = folder / "model.toml", folder / "rec.csv"
    model.write_text(EXAMPLE.read_text().replace("k3 = 1e8 ", "k3 = 0.0 ", 1))
    assert main(["simulate", "--model", str(model), "--excitation", "multisine", "--duration", "10",
                 "--amplitude", "0.75", "--csv", str(rec), "--out", str(folder / "sim")]) == 0
    return load_problem(rec, Inputs(gear_ratio=160, base=())).predictor.m


def test_a_bending_rod_keeps_the_catalogue_start(bending):
    """The rigid link's equation explains little of the bending rod's link torque, and its
    coefficients (a tip mass 3.5x the truth, a negative Coulomb level, a 200x bearing damping)
    would start the fit far off."""
    started = estimate(bending, ArmSpec()).values
    assert not {"mass.tip", "gravity.g", "load_friction.fc", "load_friction.viscous"} & set(started)


def test_a_gear_that_lags_its_deflection_is_not_read_as_a_late_link_encoder(bending):
    """The gear's damper (D / k = 0.2 ms) and its hysteresis move the measured deflection by a
    term in delta': a skew regression without that column reads it as the link encoder's lag
    (0.17 ms; the truth is none), the start the skew's screen then stands in for them from."""
    assert abs(estimate(bending, ArmSpec()).values.get("sensor_skew.lag", 0.0)) < 5e-5
