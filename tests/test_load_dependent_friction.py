"""Load-dependent friction: the friction levels (the static map's or 2SEP's) grow by g |T| / N with
the torque T the gear transmits. Checked by the steady speed it sets against a viscous load, by
recovery of a known gain from a recording, and by its place beside either friction law."""
from __future__ import annotations

import numpy as np
import pytest

import mjjoint
from mjjoint.assets import ArmSpec
from mjjoint.diagnosis.loop import candidates_for
from mjjoint.identify.effects import check_effects
from mjjoint.identify.fit import fit
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.joint import JointParams
from mjjoint.physics.load import LoadFriction
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.physics.twosep import TwoSEP
from mjjoint.recordings import Recording

N = 160.0
FC, SIGMA, BEARING = 0.05, 2e-4, 5.0   # motor Coulomb [N m], motor viscous, link-side viscous [N m s/rad]


def steady_speed(law, gain: float, u: float) -> float:
    """The motor speed a constant torque ``u`` settles at, the link's bearing purely viscous."""
    joint = JointParams(friction=law(fc=FC, fs=FC, sigma=SIGMA, load_gain=gain),
                        load_friction=LoadFriction(fc=0.0, viscous=BEARING))
    trace = mjjoint.simulate(np.full(3000, u), arm=ArmSpec(segments=0, gravity=0.0), joint=joint)
    return float(np.mean(trace.qd[-200:]))


@pytest.mark.parametrize("law", [StaticFriction, TwoSEP])
@pytest.mark.parametrize("gain", [0.0, 0.2, 0.6])
def test_the_steady_speed_balances_the_load_raised_friction(law, gain):
    # At a steady speed w the gear carries T = BEARING w / N, and the motor's torque balances
    # T / N + Fc + gain T / N + sigma w: w = (u - Fc) / ((1 + gain) BEARING / N^2 + sigma).
    # 2SEP settles there too: its pre-sliding saturated at the raised Coulomb level, its lag at S(w).
    u = 0.1
    expected = (u - FC) / ((1.0 + gain) * BEARING / N**2 + SIGMA)
    assert steady_speed(law, gain, u) == pytest.approx(expected, rel=0.01)


PHYSICS = ("coulomb_friction", "viscous_friction", "gravity", "linear_stiffness", "transmission_damping",
           "load_dependent_friction")
TRUTH = {"coulomb_friction.fc": 0.05, "viscous_friction.sigma": 2e-4, "linear_stiffness.k1": 1e4,
         "transmission_damping.d": 1.0, "load_dependent_friction.gain": 0.3}


def test_a_known_gain_is_recovered_from_a_recording():
    truth = Structure.create(PHYSICS, ArmSpec(segments=0), N, TRUTH)
    arm, joint = truth.model_params()
    trace = mjjoint.simulate(mjjoint.Multisine().sample(1000, 6), arm=arm, joint=joint)
    rec = Recording(t=trace.t, u=trace.u, q=trace.q, theta=trace.theta, tau=trace.tau)
    pred = Predictor(Measured.from_recording(rec, N), WindowDesign())
    start = Structure.create(PHYSICS, ArmSpec(segments=0), N, {**TRUTH, "load_dependent_friction.gain": 0.05})
    res = fit(pred, start, names=("coulomb_friction.fc", "load_dependent_friction.gain"), max_iter=15)
    v = res.structure.values
    assert v["load_dependent_friction.gain"] == pytest.approx(0.3, rel=0.05)
    assert v["coulomb_friction.fc"] == pytest.approx(0.05, rel=0.05)
    lo, hi = res.intervals["load_dependent_friction.gain"]
    assert lo <= 0.3 <= hi


def test_it_is_screened_beside_either_friction_law_and_kept_by_2sep():
    check_effects(["coulomb_friction", "dynamic_friction", "load_dependent_friction"])
    for effects in (("coulomb_friction",), ("coulomb_friction", "dynamic_friction")):
        assert "load_dependent_friction" in candidates_for(Structure.create(effects, ArmSpec(), N))
    # whichever of the two a structure applies first, the model carries both
    for order in (("load_dependent_friction", "dynamic_friction"), ("dynamic_friction", "load_dependent_friction")):
        s = Structure.create(("coulomb_friction",) + order, ArmSpec(), N, {"load_dependent_friction.gain": 0.3})
        friction = s.model_params()[1].friction
        assert isinstance(friction, TwoSEP) and friction.load_gain == pytest.approx(0.3)
    for law in (StaticFriction, TwoSEP):
        with pytest.raises(ValueError, match="load_gain"):
            law(load_gain=1.0)


def test_a_model_file_keeps_the_gain_and_maps_back_onto_the_effect(tmp_path):
    from mjjoint.identify.from_model import structure_from_model
    from mjjoint.modelfile import dump_model_file, load_model_file
    truth = Structure.create(PHYSICS, ArmSpec(segments=0), N, TRUTH)
    arm, joint = truth.model_params()
    model = load_model_file(dump_model_file(tmp_path / "m.toml", arm, joint))
    structure, _ = structure_from_model(model, N)
    assert "load_dependent_friction" in structure.effects
    assert structure.values["load_dependent_friction.gain"] == pytest.approx(0.3)
