"""The fitted model exported as DIR/model.toml, which `mjjoint simulate --model` takes back.

A recording of a friction-and-gear joint, started at rest, is fitted by `mjjoint fit`; the
exported model, simulated by `mjjoint simulate --model DIR/model.toml --excitation file --file
REC`, gives the fitted structure's own simulation of the recording's input, and the motor
angle of the fit's windowed prediction of the first window (which starts from the same rest).
"""
from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from mjjoint.assets import ArmSpec
from mjjoint.cli import main
from mjjoint.excitation import Multisine
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.modelfile import load_model_file
from mjjoint.recordings import read_recording
from mjjoint.sim import Simulator

GEAR = 160.0
EFFECTS = ("linear_stiffness", "transmission_damping", "coulomb_friction", "viscous_friction")
TRUTH = {"linear_stiffness.k1": 1e4, "transmission_damping.d": 2.0, "coulomb_friction.fc": 0.02,
         "viscous_friction.sigma": 0.002}


def simulator(structure: Structure) -> Simulator:
    arm, joint = structure.model_params()
    return Simulator(arm=arm, joint=joint)


def quiet(argv: list[str]) -> int:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main(argv)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    d = tmp_path_factory.mktemp("export")
    arm, joint = Structure.create(EFFECTS, ArmSpec(), GEAR, TRUTH).model_params()
    u = Multisine(amplitude=0.05, f_min=1.0, f_max=20.0, seed=4).sample(1000.0, 2.0)
    rec = Simulator(arm=arm, joint=joint).run(u).to_csv(d / "rec.csv")
    out = d / "fit"
    assert quiet(["fit", str(rec), "--gear-ratio", str(GEAR), "--base", ",".join(EFFECTS),
                  "--window-length", "0.1", "--max-iter", "3", "--out", str(out)]) == 0
    values = json.loads((out / "fit.json").read_text())["structure"]["parameters"]
    return rec, out, Structure.create(EFFECTS, ArmSpec(), GEAR, values)


def test_exported_model_resimulates_the_fitted_model(fitted, tmp_path, monkeypatch):
    rec, out, structure = fitted
    assert "model.toml" in json.loads((out / "run.json").read_text())["files"]
    model = load_model_file(out / "model.toml")
    assert (model.arm, model.joint) == structure.model_params() and model.sample_rate == pytest.approx(1000.0)
    monkeypatch.chdir(tmp_path)
    assert quiet(["simulate", "--model", str(out / "model.toml"), "--excitation", "file", "--file", str(rec),
                  "--csv", "sim.csv"]) == 0
    sim = np.genfromtxt(tmp_path / "sim.csv", delimiter=",", names=True)
    measured = read_recording(rec)
    own = simulator(structure).run(measured.u)
    assert len(sim) == measured.n
    for name in ("u", "q", "theta", "tau"):
        np.testing.assert_allclose(sim[name], getattr(own, name), rtol=0, atol=1e-9 * np.ptp(getattr(own, name)),
                                   err_msg=name)
    # The fit's own windowed prediction: its first window starts where the simulation does, at rest
    # (up to the start velocities, one-sided derivatives at the recording's first sample, which
    # ring in the lightly damped gear: tau is not compared).
    predictor = Predictor(Measured.from_recording(measured, GEAR), WindowDesign(length=0.1), nthread=1)
    assert predictor.starts[0] == 0
    (pred,) = predictor.predict([structure], np.array([0]))
    n = predictor.nwin_samples
    np.testing.assert_allclose(pred["q"][0], sim["q"][:n], rtol=0, atol=0.02 * np.ptp(sim["q"][:n]))


def test_a_changed_model_does_not_match(fitted, tmp_path, monkeypatch):
    """The comparison above can fail: the truth's stiffness doubled gives another trace."""
    rec, out, structure = fitted
    text = (out / "model.toml").read_text()
    k1 = structure.values["linear_stiffness.k1"]
    changed = tmp_path / "changed.toml"
    changed.write_text(text.replace(f"k1 = {k1!r}", f"k1 = {2 * k1!r}"))
    assert text != changed.read_text()
    monkeypatch.chdir(tmp_path)
    assert quiet(["simulate", "--model", str(changed), "--excitation", "file", "--file", str(rec), "--csv", "c.csv"]) == 0
    sim = np.genfromtxt(tmp_path / "c.csv", delimiter=",", names=True)
    own = simulator(structure).run(read_recording(rec).u)
    assert np.max(np.abs(sim["tau"] - own.tau)) > 0.01 * np.ptp(own.tau)
