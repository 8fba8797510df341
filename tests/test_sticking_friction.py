"""Sticking friction: the motor's dry friction with its exact sign, so the rotor holds at rest up
to its break-away level where the base's regularised sign lets it creep. Checked by which form a
recording of each prefers (the wrong one misses it by orders of magnitude), by the diagnosis
naming it when asked, by its exclusion of 2SEP and by a model file's round trip."""
from __future__ import annotations

import numpy as np
import pytest

import mjjoint
from mjjoint.assets import ArmSpec
from mjjoint.diagnosis.loop import candidates_for
from mjjoint.diagnosis.rests import ROTOR_HOLDS
from mjjoint.identify.effects import check_effects
from mjjoint.identify.fit import fit
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.recordings import Recording

N = 160.0
BASE = ("coulomb_friction", "viscous_friction", "load_friction", "gravity", "linear_stiffness",
        "transmission_damping")
STICKING = BASE + ("sticking_friction",)
TRUTH = {"coulomb_friction.fc": 0.05, "viscous_friction.sigma": 2e-4, "linear_stiffness.k1": 1e4,
         "transmission_damping.d": 1.0}


def recording(effects, duration: float = 6.0) -> Recording:
    arm, joint = Structure.create(effects, ArmSpec(segments=0), N, TRUTH).model_params()
    trace = mjjoint.simulate(mjjoint.Multisine().sample(1000, duration), arm=arm, joint=joint)
    return Recording(t=trace.t, u=trace.u, q=trace.q, theta=trace.theta, tau=trace.tau)


def test_the_effect_makes_the_motor_friction_sign_exact():
    _, joint = Structure.create(STICKING, ArmSpec(segments=0), N, TRUTH).model_params()
    assert isinstance(joint.friction, StaticFriction) and joint.friction.v_eps == 0.0
    _, regularised = Structure.create(BASE, ArmSpec(segments=0), N, TRUTH).model_params()
    assert regularised.friction.v_eps > 0.0


@pytest.mark.parametrize("truth", [BASE, STICKING], ids=["regularised truth", "sticking truth"])
def test_each_recording_prefers_its_own_form(truth):
    """Fitted from 20 % off, the truth's own form predicts its held-out windows to near the
    integration's floor; the other form misses them by more than 100x the cost."""
    predictor = Predictor(Measured.from_recording(recording(truth), N), WindowDesign())
    cost = {}
    for model in (BASE, STICKING):
        start = Structure.create(model, ArmSpec(segments=0), N, {k: 1.2 * v for k, v in TRUTH.items()})
        cost[model] = fit(predictor, start, max_iter=15).cost_test
    other = STICKING if truth == BASE else BASE
    assert cost[other] > 100 * cost[truth], cost


def test_it_is_screened_when_asked_or_shown_and_excludes_2sep():
    with pytest.raises(ValueError, match="cannot be in one model with"):
        check_effects(["coulomb_friction", "dynamic_friction", "sticking_friction"])
    static = Structure.create(("coulomb_friction",), ArmSpec(), N)
    assert "sticking_friction" not in candidates_for(static)  # by default: a tie with 2SEP would go to it
    # ... unless the base creeps through the recording's rests (diagnosis.rests)
    assert "coulomb_friction+sticking_friction" in candidates_for(Structure.create((), ArmSpec(), N),
                                                                  shown=(ROTOR_HOLDS,))
    assert "sticking_friction" in candidates_for(static, shown=(ROTOR_HOLDS,))
    assert candidates_for(static, ("sticking_friction", "dynamic_friction")) == ["sticking_friction",
                                                                                "dynamic_friction"]
    with_2sep = Structure.create(("coulomb_friction", "dynamic_friction"), ArmSpec(), N)
    assert candidates_for(with_2sep, ("sticking_friction",)) == []


def test_a_model_file_with_the_exact_sign_maps_back_onto_the_effect(tmp_path):
    from mjjoint.identify.from_model import structure_from_model
    from mjjoint.modelfile import dump_model_file, load_model_file
    arm, joint = Structure.create(STICKING, ArmSpec(segments=0), N, TRUTH).model_params()
    model = load_model_file(dump_model_file(tmp_path / "m.toml", arm, joint))
    structure, notes = structure_from_model(model, N)
    assert "sticking_friction" in structure.effects
    assert structure.model_params()[1].friction.v_eps == 0.0
    assert not notes  # nothing of the file left out


@pytest.mark.slow
def test_the_diagnosis_names_a_sticking_motor(tmp_path):
    """A recording of the sticking motor, diagnosed from the regularised base with the exact sign
    asked for beside 2SEP and the Stribeck curve: the exact sign is named and the final model
    predicts the held-out windows to its floor."""
    from mjjoint.recordings import write_recording
    path = tmp_path / "rec.csv"
    write_recording(path, recording(STICKING, duration=8.0))
    options = mjjoint.DiagnoseOptions(candidates=("sticking_friction", "dynamic_friction", "stribeck_friction"))
    diagnosis = mjjoint.diagnose(path, gear_ratio=N, base=list(BASE), options=options)
    assert diagnosis.missing == ["sticking_friction"], diagnosis.verdict
    assert max(diagnosis.final.nrmse_test.values()) < 0.01
    assert np.isfinite(diagnosis.final.cost_test)
