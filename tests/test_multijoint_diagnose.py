"""``mjjoint diagnose`` / ``fit`` on a multi-joint recording: each joint on its own.

The arm is two elastic joints with orthogonal axes (a yaw joint about z carrying a pitch joint
about y, the first two joints of the shipped arm3): their coupling is of second order in the
motion, so each joint seen alone (its own bodies, the rest frozen as a rigid load) predicts
its recording well while both move. The pitch joint's gear has backlash that its starting
model lacks; the yaw joint's model is complete. In the planar arm the coupling is of first
order and swamps a single-joint view when the other joint moves (a property checked below,
and the limit docs/multijoint.md describes). Budgets are cut to 3 s of data: one round, two
candidates, few LM iterations.
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import json

import numpy as np
import pytest
from test_multijoint import lock

from mjjoint.assets import load_model
from mjjoint.assets.joint_view import single_joint_models
from mjjoint.assets.serial import build_serial_arm
from mjjoint.assets.serial_file import SerialArmFile, read_model_file
from mjjoint.cli import main
from mjjoint.identify.from_model import structure_from_model
from mjjoint.trace_recording import recording, write_traces_csv
from mjjoint.tracking import track
from mjjoint.identify.fit import evaluate
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import read_recording
from mjjoint.sim import Simulator

BACKLASH = 4e-4  # [rad] play of the pitch gear, inside the benchmark's 2e-4-6e-4 (benchmark/cases.py)
DURATION = 3.0   # [s]: 30 windows of 0.1 s, 8 held out (the rank test needs >= 5)
FAST = ["--window-length", "0.1", "--max-rounds", "1", "--candidates", "backlash,torque_ripple",
        "--fit-iter", "4", "--screen-iter", "4"]

# Both joints: Coulomb + viscous motor friction, a linear elastic gear with damping; nothing else.
ARM_TOML = """\
[[joint]]                  # yaw about z: a rigid 0.15 m bracket along x, as in arm3
[joint.arm]
axis = [0.0, 0.0, 1.0]
direction = [1.0, 0.0, 0.0]
segments = 0
rod_length = 0.15
rod_mass = 0.5
max_current = 4.0
[joint.friction]
kind = "static"
fc = 0.03
fs = 0.03
sigma = 2e-4
[joint.transmission]
gear_ratio = 160.0
k1 = 1e4
k3 = 0.0
damping = 2.0
[joint.hysteresis]
kind = "none"
[joint.load_friction]
kind = "none"

[[joint]]                  # pitch about y at the bracket's end: the elbow drive of arm2_planar, rigid rod
[joint.arm]
segments = 0
rod_length = 0.3
rod_mass = 0.255
tip_mass = 1.0
motor_inertia = 2.5e-5
motor_mass = 0.25
housing_mass = 0.8
hub_mass = 0.5
k_m = 0.125
max_current = 4.0
[joint.friction]
kind = "static"
fc = 0.02
fs = 0.02
sigma = 1e-4
[joint.transmission]
gear_ratio = 100.0
k1 = 5e3
k3 = 0.0
damping = 1.0
[joint.hysteresis]
kind = "none"
[joint.load_friction]
kind = "none"
"""


def with_backlash(arm: SerialArmFile, j: int, width: float) -> SerialArmFile:
    js = arm.joints[j - 1]
    tr = dataclasses.replace(js.joint.transmission, backlash=width)
    joints = list(arm.joints)
    joints[j - 1] = dataclasses.replace(js, joint=dataclasses.replace(js.joint, transmission=tr))
    return dataclasses.replace(arm, joints=tuple(joints))


def references(n_joints: int, moving=None) -> np.ndarray:
    """Link references: per joint three sines (0.7-5.3 Hz, 0.2 rad peak to peak), faded in over 0.2 s."""
    t = np.arange(int(DURATION * 1000)) / 1000
    freqs = ((0.7, 1.9, 4.3), (0.9, 2.3, 5.3), (0.8, 2.1, 4.7))
    ref = np.zeros((len(t), n_joints))
    for j in range(n_joints) if moving is None else moving:
        ref[:, j] = 0.1 / 3 * sum(np.sin(2 * np.pi * f * t + (j + 1) * k) for k, f in enumerate(freqs[j]))
    return ref * np.minimum(1.0, t / 0.2)[:, None]


def run_track(model, ref: np.ndarray):
    """Closed loop: motor-side PD on each joint (~5 Hz at the link, as in test_multijoint)."""
    return track(Simulator(model), ref, kp=[0.1, 0.2], kd=0.004)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("arm")
    model = d / "arm.toml"
    model.write_text(ARM_TOML)
    truth = with_backlash(read_model_file(model), 2, BACKLASH)
    csv = write_traces_csv(d / "arm.csv", run_track(truth.compile(), references(2)))
    return {"dir": d, "model": model, "csv": csv}


@pytest.fixture(scope="module")
def diagnosed(files):
    out = files["dir"] / "diag"
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(io.StringIO()):
        assert main(["diagnose", str(files["csv"]), "--model", str(files["model"]), *FAST, "--out", str(out)]) == 0
    return out, stdout.getvalue()


def test_the_mismatch_is_reported_in_joint_2_and_nothing_is_added_to_joint_1(diagnosed):
    out, stdout = diagnosed
    top = json.loads((out / "diagnosis.json").read_text())
    assert top["mismatch_in"] == [2]
    joint1, joint2 = top["joints"]["1"], top["joints"]["2"]
    assert joint1["missing"] == [] and joint1["steps"] == []
    assert joint2["missing"] == ["backlash"]
    assert joint2["final_model"]["parameters"]["backlash.width"] == pytest.approx(BACKLASH, rel=0.1)
    before, after = joint2["initial_fit"]["nrmse_heldout"], joint2["final_fit"]["nrmse_heldout"]
    assert after["tau"] < before["tau"] / 2  # the play explains most of what the base model missed
    assert "joint 2" in top["verdict"] and "backlash" in top["verdict"]
    assert stdout.splitlines()[-2] == f"verdict: {top['verdict']}"


def test_each_joint_gets_the_usual_report_and_the_index_links_them(diagnosed):
    out, _ = diagnosed
    top = json.loads((out / "diagnosis.json").read_text())
    for j in ("1", "2"):
        folder = out / f"joint{j}"
        assert {"diagnosis.json", "index.html", "traces.rrd", "run.json", "heldout_windows.png"} <= \
            {p.name for p in folder.iterdir()}
        assert json.loads((folder / "diagnosis.json").read_text()) == top["joints"][j]
        assert json.loads((folder / "run.json").read_text())["joint"] == int(j)
    index = (out / "index.html").read_text()
    assert 'href="joint1/index.html"' in index and 'href="joint2/index.html"' in index
    assert set(json.loads((out / "run.json").read_text())["files"]) >= {"joint1/", "joint2/", "diagnosis.json"}


def test_fit_on_selected_joints_takes_one_gear_ratio_per_joint(files, tmp_path):
    """--base with --gear-ratio 160,100 --joint 2: only the pitch joint is fitted, with gear 100.

    The gear's stiffness is the fitted k1 of delta = q / N - theta: with the yaw joint's 160 the
    deflection would be off by q (1/100 - 1/160), tens of times the real one."""
    out = tmp_path / "fit"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["fit", str(files["csv"]), "--gear-ratio", "160,100", "--joint", "2", "--base",
                     "coulomb_friction,viscous_friction,gravity,linear_stiffness,transmission_damping",
                     "--window-length", "0.1", "--max-iter", "4", "--out", str(out)]) == 0
    top = json.loads((out / "fit.json").read_text())
    assert list(top["joints"]) == ["2"] and not (out / "joint1").exists()
    assert top["joints"]["2"] == json.loads((out / "joint2" / "fit.json").read_text())
    k1 = top["joints"]["2"]["structure"]["parameters"]["linear_stiffness.k1"]
    assert 0.5 * 5e3 < k1 < 2 * 5e3


def test_a_joint_view_moves_like_the_arm_with_the_other_joint_locked(files):
    """Joint j's single-joint view under the motor torque the locked arm's joint j got: the
    same q, theta and tau within 10x the lock's own slack (the other joint moves by eps; a
    floor of 1e-12 for rounding over the run). Inertia and static moment are lumped exactly."""
    arm = read_model_file(files["model"])
    for j, other in ((1, 2), (2, 1)):
        spec = build_serial_arm(list(arm.joints), arm.world)
        lock(spec, f"motor{other}", f"link{other}")
        traces = run_track(load_model(spec), references(2, moving=[j - 1]))
        chain, held = traces[j - 1], traces[other - 1]
        eps = max(np.abs(held.theta).max(), np.abs(held.q / held.gear_ratio).max(), 1e-12)
        view, _ = single_joint_models(arm)[j - 1]
        alone = Simulator(view.compile()).run(chain.u)
        k1 = arm.joints[j - 1].joint.transmission.k1
        assert np.ptp(chain.theta) > 0.1  # the joint really moved
        assert np.abs(alone.theta - chain.theta).max() < 10 * eps
        assert np.abs(alone.q - chain.q).max() / chain.gear_ratio < 10 * eps
        assert np.abs(alone.tau - chain.tau).max() < 10 * eps * k1


def _nrmse_at_truth(model, rec) -> dict[str, float]:
    """Held-out NRMSE of a single-joint model file's structure on a recording, at its own values (no fit)."""
    base, _ = structure_from_model(model, None)
    predictor = Predictor(Measured.from_recording(rec, base.gear_ratio), WindowDesign(length=0.1))
    return evaluate(predictor, base)[3]


def test_the_other_joints_motion_loads_a_joint_at_first_order_only_with_parallel_axes(files):
    """Both joints moving: with orthogonal axes each joint's view (true values, no fit) predicts
    its deflection and torque far better than with the same joints on parallel axes (the first
    joint turned to pitch: a planar arm), where the other link's acceleration loads the joint
    at first order, as strongly as its own motion."""
    arm = read_model_file(files["model"])
    first = dataclasses.replace(arm.joints[0], axis=(0.0, 1.0, 0.0), direction=(0.0, 0.0, -1.0))
    planar = dataclasses.replace(arm, joints=(first, arm.joints[1]))
    nrmse = {}
    for name, a in (("orthogonal", arm), ("parallel", planar)):
        rec = recording(run_track(a.compile(), references(2)))
        nrmse[name] = [_nrmse_at_truth(view, rec.joint(j)) for j, (view, _) in enumerate(single_joint_models(a), 1)]
    for j in (0, 1):
        for s in ("delta", "tau"):
            assert nrmse["parallel"][j][s] > 4 * nrmse["orthogonal"][j][s], (j + 1, s, nrmse)


@pytest.mark.parametrize("argv, message", [
    (["{csv}", "--model", "{model}", "--joint", "3"], "--joint 3: {csv} holds 2 joints (1-2)"),
    (["{csv}", "--gear-ratio", "160,100,50"], "--gear-ratio gives 3 values; the recording holds 2 joints"),
    (["{csv}", "--gear-ratio", "160,-100"], "--gear-ratio -100 must be positive"),
    (["{csv}", "--gear-ratio", "160,x"], "'160,x' is not a number"),
    (["{csv}", "--model", "{model}", "--gear-ratio", "160"], "joint 2: --gear-ratio 160 differs"),
    (["{csv}", "--gear-ratio", "160", "--joint", "0"], "joints are numbered from 1"),
    (["{single}", "--gear-ratio", "160", "--joint", "1"], "holds one joint"),
])
def test_bad_joint_options_fail_in_one_line_with_exit_2(files, tmp_path, capsys, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)  # missing folders of --out may be created here
    single = tmp_path / "single.csv"
    single.write_text("t,u,q,theta\n" + "".join(f"{0.001 * i},0,0,0\n" for i in range(20)))
    names = {"model": files["model"], "csv": files["csv"], "single": single}
    out = tmp_path / "new" / "out"
    assert main(["diagnose", *(a.format(**names) for a in argv), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("mjjoint: error: ") and message.format(**names) in err, err
    assert not (tmp_path / "new").exists()


def test_the_recording_holds_what_the_arm_did(files):
    rec = read_recording(files["csv"])
    assert rec.n_joints == 2 and rec.n == int(DURATION * 1000)
    assert all(np.ptp(rec.joint(j).theta) > 0.1 for j in (1, 2))  # both joints really moved
