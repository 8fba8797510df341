"""``mjjoint.fit`` and ``mjjoint.diagnose``: the command line's fit and diagnosis as one Python call.

A 3 s recording of an elastic gear with a 3 ms input delay; the starting model is the same gear
without the delay (a model file written from the truth). Budgets are cut as in
tests/test_cli_diagnose.py.
"""
from __future__ import annotations

import json
import warnings

import pytest

import mjjoint
from mjjoint.assets import ArmSpec
from mjjoint.cli import main
from mjjoint.excitation import Multisine
from mjjoint.identify.structure import Structure
from mjjoint.modelfile import dump_model_file
from mjjoint.physics.transmission import Transmission
from mjjoint.sim import Simulator

GEAR = 160.0
DELAY = 3e-3
NOMINAL = ArmSpec(segments=0, gravity=0.0)
GEAR_EFFECTS = ("linear_stiffness", "transmission_damping")
GEAR_VALUES = {"linear_stiffness.k1": 1e4, "transmission_damping.d": 2.0}
DESIGN = mjjoint.WindowDesign(length=0.1)
MAX_ITER = 6


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("api")
    arm, joint = Structure.create(GEAR_EFFECTS + ("input_delay",), NOMINAL, GEAR,
                                  {**GEAR_VALUES, "input_delay.delay": DELAY}).model_params()
    u = Multisine(amplitude=0.05, f_min=1.0, f_max=30.0, seed=1).sample(1000.0, 3.0)
    rec = Simulator(arm=arm, joint=joint).run(u).to_csv(d / "delayed.csv")
    arm, joint = Structure.create(GEAR_EFFECTS, NOMINAL, GEAR, GEAR_VALUES).model_params()
    return {"dir": d, "rec": rec, "model": dump_model_file(d / "gear.toml", arm, joint)}


@pytest.fixture(scope="module")
def fitted(files):
    return mjjoint.fit(files["rec"], model=files["model"], design=DESIGN, max_iter=MAX_ITER)


def test_fit_is_the_command_line_fit(files, fitted):
    out = files["dir"] / "cli_fit"
    assert main(["fit", str(files["rec"]), "--model", str(files["model"]), "--window-length", "0.1",
                 "--max-iter", str(MAX_ITER), "--out", str(out)]) == 0
    cli = json.loads((out / "fit.json").read_text())
    assert isinstance(fitted, mjjoint.FitResult)
    assert fitted.structure.values == pytest.approx(cli["structure"]["parameters"], rel=1e-12)
    assert fitted.nrmse_test == pytest.approx(cli["nrmse_test"], rel=1e-12)
    assert set(fitted.intervals) == set(fitted.structure.values)


def test_a_recording_object_fits_as_its_file(files, fitted):
    rec = mjjoint.read_recording(files["rec"])
    again = mjjoint.fit(rec, model=files["model"], design=DESIGN, max_iter=MAX_ITER)
    assert again.structure.values == fitted.structure.values


def test_each_joint_of_a_multi_joint_recording_fits_on_its_own(files, fitted):
    rec = mjjoint.read_recording(files["rec"])
    both = mjjoint.fit(mjjoint.MultiRecording((rec, rec)), gear_ratio=(GEAR, GEAR), base=GEAR_EFFECTS,
                       design=DESIGN, max_iter=MAX_ITER)
    assert set(both) == {1, 2}
    single = mjjoint.fit(rec, gear_ratio=GEAR, base=list(GEAR_EFFECTS), design=DESIGN, max_iter=MAX_ITER)
    for result in both.values():
        assert result.structure.values == single.structure.values


def test_diagnose_names_the_delay_it_was_not_told(files):
    options = mjjoint.DiagnoseOptions(max_rounds=1, candidates=("backlash", "input_delay"), fit_iter=6,
                                      screen_iter=4)
    lines = []
    diag = mjjoint.diagnose(mjjoint.read_recording(files["rec"]), model=files["model"], design=DESIGN,
                            options=options, progress=lines.append)
    assert isinstance(diag, mjjoint.Diagnosis)
    assert diag.missing == ["input_delay"]
    assert diag.final.structure.values["input_delay.delay"] == pytest.approx(DELAY, rel=0.1)
    assert diag.final.cost_test < 0.5 * diag.initial.cost_test
    assert lines and lines[0].startswith("fitting the base model")


def test_what_a_model_file_cannot_hold_is_a_warning(files, tmp_path):
    arm, joint = Structure.create(GEAR_EFFECTS, NOMINAL, GEAR, GEAR_VALUES).model_params()
    joint = joint.replace(transmission=Transmission(gear_ratio=GEAR, k1=1e4, k2=5.0, damping=2.0, hysteresis=None))
    model = dump_model_file(tmp_path / "k2.toml", arm, joint)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mjjoint.fit(files["rec"], model=model, design=DESIGN, max_iter=1)
    assert any("transmission.k2=5" in str(w.message) for w in caught)


@pytest.mark.parametrize(("inputs", "error", "message"), [
    ({}, ValueError, "gear_ratio N is required"),
    ({"gear_ratio": -1.0}, ValueError, "gear_ratio -1 must be positive"),
    ({"gear_ratio": GEAR, "base": ["no_such_effect"]}, ValueError, "base: "),
    ({"gear_ratio": GEAR, "plant": "crane"}, ValueError, "plant 'crane' is not one of"),
    ({"gear_ratio": GEAR, "max_iter": 0}, ValueError, "max_iter=0"),
    ({"gear_ratio": GEAR, "joints": (0,)}, ValueError, r"joints: joints are numbered from 1, got \(0,\)"),
    ({"gear_ratio": GEAR, "window": 0.1}, TypeError, "window"),
])
def test_bad_inputs_fail_naming_the_python_input(files, inputs, error, message):
    with pytest.raises(error, match=message):
        mjjoint.fit(files["rec"], **inputs)


def test_diagnose_takes_only_diagnose_options(files):
    with pytest.raises(TypeError, match="DiagnoseOptions"):
        mjjoint.diagnose(files["rec"], gear_ratio=GEAR, options={"max_rounds": 1})
