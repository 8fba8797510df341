"""The MuJoCo stages a prediction does not read are off in the models it rolls out
(identify.stages), without changing a bit of any prediction; a model that can make a constraint
keeps them."""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mjjoint.identify.windows as windows
from mjjoint.assets import build_arm
from mjjoint.benchmark.cases import GEAR_RATIO, make_case
from mjjoint.identify.stages import can_constrain, for_prediction
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import Recording
from mjjoint.rehearse import LabProgram, record

D = mujoco.mjtDisableBit


def _forget_models() -> None:
    """Empty the compiled-model memo, and the stability memo keyed by those models' ids."""
    windows._MODEL_CACHE.clear()
    windows._STABLE.clear()


def test_predictions_are_bit_identical_with_the_stages_off(monkeypatch):
    truth = make_case("none", 0).truth
    cols = record(*truth.model_params(), LabProgram(duration=3.0, seed=0))
    pred = Predictor(Measured.from_recording(Recording(gear_ratio=GEAR_RATIO, meta={}, **cols), GEAR_RATIO),
                     WindowDesign(seed=0))
    # A flexible rod with a play and Bouc-Wen, and the rigid rod the recording was made with.
    structures = [truth.with_effect("link_flexibility", {"link_flexibility.ei": 500.0}).with_effect("backlash"),
                  truth]
    _forget_models()
    off = pred.predict(structures)
    flags = {windows._compile(*s.model_params()).opt.disableflags for s in structures}
    assert flags == {int(D.mjDSBL_SENSOR) | int(D.mjDSBL_CONSTRAINT) | int(D.mjDSBL_CONTACT)}
    monkeypatch.setattr(windows, "for_prediction", lambda model: model)
    _forget_models()
    on = pred.predict(structures)
    assert {windows._compile(*s.model_params()).opt.disableflags for s in structures} == {0}
    _forget_models()
    for a, b in zip(off, on):
        assert a.keys() == b.keys()
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])


@pytest.mark.parametrize("change", ["limit", "contact", "equality", "frictionloss"])
def test_a_model_that_can_constrain_keeps_its_constraint_stages(change):
    spec = build_arm(scene=False)
    assert not can_constrain(spec.compile())
    if change == "limit":
        spec.joint("link").limited = mujoco.mjtLimited.mjLIMITED_TRUE
        spec.joint("link").range = [-1.0, 1.0]
    elif change == "contact":
        spec.geoms[0].contype = spec.geoms[0].conaffinity = 1
    elif change == "equality":
        spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, name1="motor", name2="link")
    else:
        spec.joint("link").frictionloss = 0.1
    model = for_prediction(spec.compile())
    assert can_constrain(model)
    assert model.opt.disableflags == int(D.mjDSBL_SENSOR)
