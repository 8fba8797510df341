"""Initial values and ranges from the recording: drives decades away from the shipped ones fit
with no --scales, and the estimator recovers known parameters of noise-free recordings."""
from __future__ import annotations

import dataclasses
import json

import mujoco
import numpy as np
import pytest

from mjjoint.assets import load_model
from mjjoint.assets.drive import DriveSpec, build_drive
from mjjoint.identify.initial import DECADES, SLOPE_STEP, estimate
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured
from mjjoint.joint import JointParams
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.physics.transmission import Transmission
from mjjoint.recordings import Recording, write_recording

# (inertia [kg m^2], Coulomb [N m], viscous [N m s/rad], reference amplitude [rad], its base
# frequency [Hz]): a small servo motor and a large robot-axis motor, 5 decades apart.
SMALL = (1e-4, 0.03, 2e-4, 2.0, 3.0)
LARGE = (10.0, 50.0, 20.0, 0.5, 1.0)


def servo_recording(j: float, fc: float, sigma: float, amplitude: float, f0: float,
                    duration: float = 6.0) -> Recording:
    """A rotary direct drive under a PD position loop (10 Hz bandwidth, 0.7 damping) tracking
    three sines at f0, 2.3 f0 and 3.7 f0; noise-free."""
    spec = DriveSpec(joint_type="hinge", mass=j, k_m=1.0, ctrl_limit=1e9, input_offset=0.0)
    # The sign regularisation as the fit will choose it (initial.Estimate.v_eps).
    v_eps = max(spec.v_eps, fc * spec.timestep / (SLOPE_STEP * j))
    friction = StaticFriction(fc=fc, fs=fc, sigma=sigma, v_eps=v_eps)
    model = load_model(build_drive(spec, JointParams(friction=friction)))
    d = mujoco.MjData(model)
    h = model.opt.timestep
    t = h * np.arange(int(round(duration / h)))
    ref = amplitude * sum(np.sin(2 * np.pi * k * f0 * t + k) for k in (1.0, 2.3, 3.7)) / 3
    w = 2 * np.pi * 10.0
    q, u = np.empty(len(t)), np.empty(len(t))
    for i in range(len(t)):
        q[i] = d.qpos[0]
        u[i] = j * w * w * (ref[i] - q[i]) - 1.4 * j * w * d.qvel[0]
        d.ctrl[0] = u[i]
        mujoco.mj_step(model, d)
    return Recording(t=t, u=u, q=q, theta=q)


@pytest.mark.parametrize("case", [SMALL, LARGE], ids=["small", "large"])
def test_the_estimator_recovers_a_drives_inertia_and_friction(case):
    j, fc, sigma = case[:3]
    e = estimate(Measured.from_recording(servo_recording(*case), 1.0, output=False))
    # Start values, for a fit that may move each DECADES either way: the inertia within 5 %,
    # the friction levels (which the J a term dwarfs on the large drive) within half.
    assert e.values["inertia.motor"] == pytest.approx(j, rel=0.05)
    assert e.values["coulomb_friction.fc"] == pytest.approx(fc, rel=0.5)
    assert e.values["viscous_friction.sigma"] == pytest.approx(sigma, rel=0.5)
    # Every range is centred on its estimate, so the truth lies far inside.
    s = Structure.create(("coulomb_friction", "viscous_friction"), DriveSpec(joint_type="hinge"), 1.0, start=e)
    for p in s.params:
        assert p.lo == pytest.approx(p.initial * 10 ** -DECADES) and p.hi == pytest.approx(p.initial * 10 ** DECADES)


@pytest.mark.parametrize("case", [SMALL, LARGE], ids=["small", "large"])
def test_fit_plant_rotary_recovers_motors_decades_apart_with_no_scales(case, tmp_path, capsys):
    from mjjoint.cli import main
    j, fc = case[:2]
    rec = tmp_path / "servo.csv"
    write_recording(rec, servo_recording(*case))
    out = tmp_path / "fit"
    assert main(["fit", str(rec), "--plant", "rotary", "--base", "coulomb_friction,viscous_friction",
                 "--window-length", "0.5", "--max-iter", "15", "--out", str(out)]) == 0
    fitted = json.loads((out / "fit.json").read_text())["structure"]["parameters"]
    # Within 5 %: the fitted model's sign regularisation is set from the estimated Fc / J
    # (Estimate.v_eps), the truth's from the true one.
    assert fitted["inertia.motor"] == pytest.approx(j, rel=0.05)
    assert fitted["coulomb_friction.fc"] == pytest.approx(fc, rel=0.05)
    assert "kg m^2" in capsys.readouterr().out  # rotary units, SI


def arm_recording(k1: float, tau: bool = True) -> Measured:
    """The shipped arm (rigid rod, no gravity, Coulomb + viscous motor friction, a linear gear)
    under an 80 -> 1 Hz chirp (through the gear's resonance), noise-free."""
    import mjjoint
    from mjjoint.assets import ArmSpec
    arm = ArmSpec(segments=0, gravity=0.0)
    joint = JointParams(friction=StaticFriction(fc=0.05, fs=0.05, sigma=2e-4), load_friction=None,
                        transmission=Transmission(gear_ratio=160.0, k1=k1, k3=0.0, damping=1.0, hysteresis=None))
    trace = mjjoint.simulate(mjjoint.Chirp(f_start=80.0).sample(1000, 5), arm=arm, joint=joint)
    rec = Recording(t=trace.t, u=trace.u, q=trace.q, theta=trace.theta, tau=trace.tau if tau else None)
    return Measured.from_recording(rec, 160.0), arm


@pytest.mark.parametrize("k1", [3e3, 3e4])
def test_the_estimator_recovers_the_gear_stiffness_from_the_torque_and_the_resonance(k1):
    measured, arm = arm_recording(k1)
    e = estimate(measured, arm.link_inertia)
    assert e.values["linear_stiffness.k1"] == pytest.approx(k1, rel=0.05)
    assert e.values["inertia.motor"] == pytest.approx(arm.motor_inertia, rel=0.05)
    assert e.values["coulomb_friction.fc"] == pytest.approx(0.05, rel=0.05)
    assert e.values["viscous_friction.sigma"] == pytest.approx(2e-4, rel=0.25)
    # Without the torque sensor: the resonance of the input-to-deflection response.
    untorqued = dataclasses.replace(measured, tau=None)
    e = estimate(untorqued, arm.link_inertia)
    assert e.resonance is not None
    assert e.values["linear_stiffness.k1"] == pytest.approx(k1, rel=0.25)


def test_a_fit_started_off_ends_on_a_bound_and_restarts_recover_the_truth():
    """J started a thousandfold low and Fc three hundredfold high: the single fit ends with
    parameters on their bounds and says which; restarts from the recording's estimates reach
    the truth, with nothing on a bound."""
    from mjjoint.identify.fit import fit
    from mjjoint.identify.windows import Predictor, WindowDesign
    j, fc = SMALL[:2]
    measured = Measured.from_recording(servo_recording(*SMALL, duration=3.0), 1.0, output=False)
    start = estimate(measured)
    nominal = DriveSpec(joint_type="hinge", v_eps=start.v_eps(DriveSpec.timestep, DriveSpec.v_eps))
    s = Structure.create(("coulomb_friction", "viscous_friction"), nominal, 1.0, start=start)
    lo = {p.name: p.lo for p in s.params}
    hi = {p.name: p.hi for p in s.params}
    off = s.with_values({"inertia.motor": lo["inertia.motor"], "coulomb_friction.fc": hi["coulomb_friction.fc"],
                         "viscous_friction.sigma": hi["viscous_friction.sigma"]})
    pred = Predictor(measured, WindowDesign(length=0.25))
    single = fit(pred, off, max_iter=10)
    assert single.on_bound and single.as_dict()["on_bound"] == list(single.on_bound)
    assert all(f"{n} = " in w and "bound" in w for n, w in zip(single.on_bound, single.warnings))
    best = fit(pred, off, max_iter=10, restarts=2)
    assert best.starts == 3 and best.on_bound == ()
    assert best.structure.values["inertia.motor"] == pytest.approx(j, rel=0.05)
    assert best.structure.values["coulomb_friction.fc"] == pytest.approx(fc, rel=0.05)
