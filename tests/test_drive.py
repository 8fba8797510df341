"""The direct drive (a joint with no transmission): physics, and identification on it."""
from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from mjjoint.assets import load_model
from mjjoint.assets.drive import DriveSpec, build_drive
from mjjoint.identify.fit import fit
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.joint import GROUND, JointParams
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.recordings import Recording

TRUTH = DriveSpec(mass=80.0, input_offset=-4.0)
FRICTION = StaticFriction(fc=25.0, fs=25.0, sigma=150.0, v_eps=1e-3)


def drive_model(spec: DriveSpec = TRUTH, friction=FRICTION) -> mujoco.MjModel:
    return load_model(build_drive(spec, JointParams(friction=friction)))


def test_a_direct_drive_needs_its_output_grounded():
    with pytest.raises(ValueError, match="transmission=none"):
        JointParams(transmission=None, link_joint="link")
    j = JointParams(transmission=None, link_joint=GROUND)
    assert j.direct_drive and j.gear_ratio == 1.0
    assert JointParams.from_config(j.to_config()) == j


def test_shipped_linear_drive_is_the_published_emps_model():
    model = load_model("mjjoint/assets/mjcf/linear_drive.xml")
    assert model.jnt_type[0] == mujoco.mjtJoint.mjJNT_SLIDE
    d = mujoco.MjData(model)
    d.qvel[0] = 0.1
    mujoco.mj_forward(model, d)
    # Janot et al. 2019: Fc sgn(v) + Fv v at 0.1 m/s, and the +3.16 N offset with no command.
    assert d.qfrc_passive[0] == pytest.approx(-(20.39 * np.tanh(100.0) + 203.5 * 0.1), rel=1e-9)
    assert d.qfrc_actuator[0] == pytest.approx(3.16, rel=1e-3)


@pytest.mark.parametrize("joint_type", ["slide", "hinge"])
def test_constant_force_reaches_the_viscous_terminal_speed(joint_type):
    """M v' = F + offset - Fc - Fv v: v -> (F + offset - Fc) / Fv, from rest, monotonically."""
    spec = dataclasses.replace(TRUTH, joint_type=joint_type)
    model = drive_model(spec)
    d = mujoco.MjData(model)
    force = 100.0
    d.ctrl[0] = force / spec.k_m
    speeds = []
    for _ in range(int(4.0 / model.opt.timestep)):  # 7.5 time constants M/Fv
        mujoco.mj_step(model, d)
        speeds.append(d.qvel[0])
    terminal = (force + spec.input_offset - FRICTION.fc) / FRICTION.sigma
    assert speeds[-1] == pytest.approx(terminal, rel=2e-3)
    assert np.all(np.diff(speeds) >= -1e-12)


def test_the_input_offset_moves_the_drive_without_a_command():
    model = drive_model(friction=None)
    d = mujoco.MjData(model)
    for _ in range(1000):
        mujoco.mj_step(model, d)
    t = 1000 * model.opt.timestep
    assert d.qpos[0] == pytest.approx(0.5 * TRUTH.input_offset / TRUTH.mass * t * t, rel=2e-3)


def closed_loop_recording(duration: float = 12.0, seed: int = 0) -> Recording:
    """A position-controlled drive as the EMPS is run: PD on a smooth multi-level reference,
    a 1 um encoder and a noisy command."""
    model = drive_model()
    d = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    h = model.opt.timestep
    n = int(round(duration / h))
    t = h * np.arange(n)
    levels = rng.uniform(0.0, 0.2, size=int(duration) + 1)
    ref = np.interp(t, np.arange(len(levels)), levels)
    ref = np.convolve(ref, np.ones(200) / 200, mode="same")
    q, u = np.empty(n), np.empty(n)
    for i in range(n):
        q[i] = np.round(d.qpos[0] / 1e-6) * 1e-6
        u[i] = 2000.0 * (ref[i] - q[i]) - 400.0 * d.qvel[0] + rng.normal(0.0, 1.0)
        d.ctrl[0] = u[i] / TRUTH.k_m
        mujoco.mj_step(model, d)
    return Recording(t=t, u=u, q=q, theta=q)


def test_fit_recovers_mass_friction_and_offset_of_a_closed_loop_drive():
    rec = closed_loop_recording()
    pred = Predictor(Measured.from_recording(rec, 1.0, output=False), WindowDesign(length=0.5))
    assert pred.signals == ("q",)
    start = Structure.create(("coulomb_friction", "viscous_friction", "input_offset"), DriveSpec(), 1.0)
    res = fit(pred, start, max_iter=30)
    v = res.structure.values
    assert v["inertia.motor"] == pytest.approx(TRUTH.mass, rel=0.05)
    assert v["coulomb_friction.fc"] == pytest.approx(FRICTION.fc, rel=0.05)
    assert v["viscous_friction.sigma"] == pytest.approx(FRICTION.sigma, rel=0.05)
    assert v["input_offset.offset"] == pytest.approx(TRUTH.input_offset, rel=0.10)


def test_drive_structures_only_offer_drive_effects():
    with pytest.raises(ValueError, match="unknown effect 'backlash'"):
        Structure.create(("backlash",), DriveSpec(), 1.0)
    s = Structure.create(("coulomb_friction",), DriveSpec(), 1.0)
    # Ranges follow the drive's force order (N), not the arm motor's (N m).
    (fc,) = [p for p in s.params if p.name == "coulomb_friction.fc"]
    assert fc.lo <= 20.0 <= fc.hi and fc.hi > 100.0


def test_cli_fits_a_linear_drive_recording(tmp_path, capsys):
    import json

    from mjjoint.cli import main
    from mjjoint.recordings import write_recording
    rec = tmp_path / "drive.csv"
    write_recording(rec, closed_loop_recording(duration=6.0))
    common = ["fit", str(rec), "--plant", "linear", "--window-length", "0.5"]
    assert main([*common, "--base", "backlash", "--out", str(tmp_path / "bad")]) == 2
    assert "unknown effect 'backlash'" in capsys.readouterr().err and not (tmp_path / "bad").exists()
    out = tmp_path / "fit"
    assert main([*common, "--base", "coulomb_friction,viscous_friction,input_offset", "--max-iter", "15",
                 "--out", str(out)]) == 0
    fitted = json.loads((out / "fit.json").read_text())["structure"]["parameters"]
    assert fitted["coulomb_friction.fc"] == pytest.approx(FRICTION.fc, rel=0.1)
    assert "N s/m" in capsys.readouterr().out  # linear units, not the arm motor's


def test_intervals_are_labelled_with_their_own_parameters_whatever_the_order_asked():
    rec = closed_loop_recording(duration=6.0)
    pred = Predictor(Measured.from_recording(rec, 1.0, output=False), WindowDesign(length=0.5))
    start = Structure.create(("coulomb_friction", "viscous_friction"), DriveSpec(), 1.0,
                             {"coulomb_friction.fc": 20.0, "viscous_friction.sigma": 100.0})
    res = fit(pred, start, ["viscous_friction.sigma", "coulomb_friction.fc"], max_iter=10)
    for name, (lo, hi) in res.intervals.items():
        assert lo <= res.structure.values[name] <= hi, name
