"""Shape factors the catalogue screens as settings rather than fits: Eq. 17's hysteresis loop
shape (gamma / beta) and Eq. 15's Stribeck shape delta; each read from a model, written back,
screened, and told apart on a recording made with it."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mjjoint import Multisine, Simulator
from mjjoint.assets import ArmSpec
from mjjoint.identify.effects import EFFECTS, HYSTERESIS_SHAPE, HYSTERESIS_SHAPES, STRIBECK_SHAPE, STRIBECK_SHAPES
from mjjoint.identify.fit import fit
from mjjoint.identify.from_model import structure_from_model
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.modelfile import ModelFile
from mjjoint.physics.boucwen import BoucWen
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.recordings import Recording

N = 160.0
RATE = 1000.0
LSB = 2 * math.pi / 2 ** 17
EFFECTS_USED = ("coulomb_friction", "viscous_friction", "linear_stiffness", "transmission_hysteresis",
                "transmission_damping")
TRUE = {"transmission_hysteresis.mu": 0.5, "transmission_hysteresis.x_u": 2e-3}


def _recording(truth: Structure, amplitude: float) -> Predictor:
    u = Multisine(amplitude=amplitude).sample(RATE, 6.0)
    tr = Simulator(truth.compile(), sample_rate=RATE).run(u)
    q = np.round(tr.q / LSB) * LSB
    rec = Recording(t=tr.t, u=tr.u, q=q, theta=tr.theta, tau=tr.tau, gear_ratio=N, meta={})
    return Predictor(Measured.from_recording(rec, N), WindowDesign())


def _truth(shape: float) -> Structure:
    return Structure.create(EFFECTS_USED, ArmSpec(segments=0), N, TRUE, {HYSTERESIS_SHAPE: shape})


@pytest.mark.parametrize("shape", HYSTERESIS_SHAPES)
def test_the_shape_builds_eq_17s_beta_and_gamma_and_reads_back(shape):
    arm, joint = _truth(shape).model_params()
    bw = joint.transmission.hysteresis
    assert isinstance(bw, BoucWen)
    assert bw.gamma == pytest.approx(shape * bw.beta)
    assert bw.x_ultimate == pytest.approx(TRUE["transmission_hysteresis.x_u"])
    read = EFFECTS["transmission_hysteresis"].read((arm, joint))
    assert read[HYSTERESIS_SHAPE] == pytest.approx(shape)
    assert read["transmission_hysteresis.mu"] == pytest.approx(0.5)


@pytest.mark.parametrize("effect, key, shapes", [("transmission_hysteresis", HYSTERESIS_SHAPE, HYSTERESIS_SHAPES),
                                                 ("stribeck_friction", STRIBECK_SHAPE, STRIBECK_SHAPES)])
def test_every_shape_is_screened(effect, key, shapes):
    variants = EFFECTS[effect].variants([], _truth(1.0))
    assert sorted(s[key] for _, s in variants) == sorted(shapes)


def test_a_model_file_with_beta_alone_keeps_its_shape():
    arm, joint = _truth(1.0).model_params()
    beta_alone = dataclasses.replace(joint.transmission, hysteresis=BoucWen(mu=0.5, beta=500.0, gamma=0.0))
    model = ModelFile(arm=arm, joint=dataclasses.replace(joint, transmission=beta_alone))
    structure, notes = structure_from_model(model, None)
    assert structure.settings[HYSTERESIS_SHAPE] == 0.0
    assert not [n for n in notes if "hysteresis" in n], notes


def _told_apart(effects, true: dict, key: str, shapes, shape: float, start: dict, amplitude: float):
    """A recording made with ``shape``, fitted from ``start`` with each of ``shapes``: the right
    shape predicts the held-out windows at least twice as well as every other, and recovers
    ``true`` within 5 %."""
    truth = Structure.create(effects, ArmSpec(segments=0), N, true, {key: shape})
    predictor = _recording(truth, amplitude)
    fits = {s: fit(predictor, Structure.create(effects, ArmSpec(segments=0), N, {**truth.values, **start}, {key: s}),
                   max_iter=15)
            for s in shapes}
    right = fits[shape]
    for other in shapes:
        if other != shape:
            assert right.cost_test < 0.5 * fits[other].cost_test, (right.cost_test, fits[other].cost_test)
    for name, value in true.items():
        assert right.structure.values[name] == pytest.approx(value, rel=0.05), name


def test_a_recording_tells_the_loop_shape_it_was_made_with():
    """A gear with beta alone (gamma = 0), against the classic loop."""
    _told_apart(EFFECTS_USED, TRUE, HYSTERESIS_SHAPE, HYSTERESIS_SHAPES, 0.0,
                {"transmission_hysteresis.mu": 0.7, "transmission_hysteresis.x_u": 3e-3}, 0.4)


STRIBECK = ("coulomb_friction", "viscous_friction", "stribeck_friction", "linear_stiffness", "transmission_damping")
TRUE_STRIBECK = {"stribeck_friction.ratio": 2.0, "stribeck_friction.vs": 3.0}


def test_the_stribeck_shape_builds_the_map_and_reads_back():
    truth = Structure.create(STRIBECK, ArmSpec(segments=0), N, TRUE_STRIBECK, {STRIBECK_SHAPE: 2.0})
    arm, joint = truth.model_params()
    assert isinstance(joint.friction, StaticFriction) and joint.friction.shape == 2.0
    assert EFFECTS["stribeck_friction"].read((arm, joint))[STRIBECK_SHAPE] == 2.0


def test_a_recording_tells_the_stribeck_shape_it_was_made_with():
    """A Gaussian Stribeck dip (delta = 2), against the exponential one."""
    _told_apart(STRIBECK, TRUE_STRIBECK, STRIBECK_SHAPE, STRIBECK_SHAPES, 2.0,
                {"stribeck_friction.ratio": 1.5, "stribeck_friction.vs": 1.5}, 0.3)
