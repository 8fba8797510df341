"""A position servo with one encoder at the output, diagnosed from its own log's layout: the
pendulum's bodies from a model file, the effects from --base, the motor torque derived from the
logged current by an expression, theta the only encoder (q = N theta, the deflection not
measured), and a light rotor whose friction needs a wider sign regularisation than the arm's."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mjjoint import Multisine, Simulator
from mjjoint.assets import ArmSpec
from mjjoint.diagnosis.floor import judged
from mjjoint.identify.effects import FRICTION_V_EPS
from mjjoint.identify.fit import fit
from mjjoint.identify.initial import ARM_SLOPE_STEP
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import WindowDesign
from mjjoint.params import fitting_timestep
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.problem import Inputs, load_problem

N = 288.35
KT = 0.338                    # [N m/A] at the output
RATE = 200.0                  # [Hz] a servo bus's log rate
LSB = 2 * math.pi / 4096      # [rad] the output encoder
BASE = ("coulomb_friction", "viscous_friction", "gravity")
PENDULUM = dict(segments=0, rod_length=0.1, rod_mass=0.01, tip_mass=0.49, hub_inertia=1e-5, motor_inertia=2.5e-8,
                k_m=1.0, max_current=1.0, gravity=9.81, timestep=5e-4)
TRUE = {"coulomb_friction.fc": 0.02 / N, "viscous_friction.sigma": 0.02 / N ** 2, "gravity.g": 9.81}
MODEL_FILE = """
[arm]
segments = 0
rod_length = 0.1
rod_mass = 0.01
tip_mass = 0.49
hub_inertia = 1e-5
motor_inertia = 2.5e-8
k_m = 1.0
max_current = 1.0
timestep = 0.0005

[transmission]
gear_ratio = 288.35
"""
COLUMNS = {"t": "entries.timestamp", "u": f"{KT}/{N}*entries.current", "q": f"{N}*entries.position",
           "theta": "entries.position"}


@pytest.fixture(scope="module")
def servo(tmp_path_factory) -> tuple[Path, Path]:
    """(log, model file): 12 s of the pendulum under a multisine current, logged as a servo bus
    logs it (records of time, current and the output encoder's counts in rad)."""
    truth = Structure.create(BASE, ArmSpec(**PENDULUM), N, TRUE, {FRICTION_V_EPS: 5.0})
    u = Multisine(amplitude=1.2e-3, f_min=0.2, f_max=4.0).sample(RATE, 12.0)
    tr = Simulator(truth.compile(), sample_rate=RATE).run(u)
    position = np.round(tr.theta / LSB) * LSB
    entries = [{"timestamp": float(t), "current": float(c), "position": float(p)}
               for t, c, p in zip(tr.t, tr.u * N / KT, position)]
    folder = tmp_path_factory.mktemp("servo")
    log, model = folder / "log.json", folder / "pendulum.toml"
    log.write_text(json.dumps({"kp": 400, "entries": entries}))
    model.write_text(MODEL_FILE)
    return log, model


def _problem(servo):
    log, model = servo
    return load_problem(log, Inputs(model=model, base=BASE, columns=COLUMNS, fit_signals=("q",),
                                    design=WindowDesign(length=0.5)))


def test_the_model_files_bodies_carry_the_listed_effects_from_the_recordings_estimates(servo):
    problem = _problem(servo)
    base = problem.base
    assert base.effects == BASE
    assert base.nominal.rod_length == 0.1 and base.nominal.segments == 0
    # The file's tip mass is the user's and stays; the friction it does not state starts from the
    # recording, not from the file's default 2SEP section.
    assert base.values["mass.tip"] == 0.49
    assert base.values["coulomb_friction.fc"] == pytest.approx(TRUE["coulomb_friction.fc"], rel=1.0)
    assert not [n for n in problem.notes if "friction" in n], problem.notes


def test_a_light_rotors_friction_gets_the_sign_regularisation_its_step_needs(servo):
    """The arm's 1 rad/s on a 2.5e-8 kg m^2 rotor: the estimated Coulomb slope would exceed what
    the explicit step integrates; the started structure widens it, and it compiles stable."""
    base = _problem(servo).base
    v_eps = base.settings[FRICTION_V_EPS]
    assert v_eps > StaticFriction.v_eps
    arm, joint = base.model_params()
    assert joint.friction.v_eps == v_eps
    h = fitting_timestep(RATE, arm.timestep)
    assert base.values["coulomb_friction.fc"] * h / (v_eps * base.values["inertia.motor"]) <= ARM_SLOPE_STEP + 1e-12


def test_one_encoders_deflection_is_neither_scored_nor_reported_and_the_fit_recovers_the_servo(servo):
    problem = _problem(servo)
    pred = problem.predictor
    assert not pred.m.link_encoder and pred.meas["delta"] is None
    result, floor, _ = judged(pred, fit(pred, problem.base, max_iter=30, restarts=1))
    assert "delta" not in result.nrmse_test and "delta" not in floor.signals
    assert result.nrmse_test["q"] < 0.05
    for name in ("coulomb_friction.fc", "viscous_friction.sigma"):
        assert result.structure.values[name] == pytest.approx(TRUE[name], rel=0.15), name


def test_scoring_the_deflection_of_one_encoder_is_refused_in_one_line(servo):
    log, model = servo
    with pytest.raises(ValueError, match="theta is q/N, one encoder's angle"):
        load_problem(log, Inputs(model=model, base=BASE, columns=COLUMNS, fit_signals=("q", "delta")))
