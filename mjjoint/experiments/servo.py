"""Generated, noise-free recordings of plants of other sizes, for the scale-free identification.

Rotary direct drives of any size under a position loop (a small servo motor and a large
robot-axis motor, decades apart in inertia and friction) and the arm with a linear gear of any
stiffness; ``tests/test_initial.py`` and ``scripts/initial_values.py`` use them.
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..assets import load_model
from ..assets.drive import DriveSpec, build_drive
from ..identify.initial import SLOPE_STEP
from ..joint import JointParams
from ..physics.stribeck import StaticFriction
from ..recordings import Recording
from ..sim import step_held


@dataclass(frozen=True)
class Servo:
    inertia: float     # [kg m^2]
    coulomb: float     # [N m]
    viscous: float     # [N m s/rad]
    amplitude: float   # [rad] of the reference
    f0: float          # [Hz] its base frequency


SMALL = Servo(1e-4, 0.03, 2e-4, 2.0, 3.0)
LARGE = Servo(10.0, 50.0, 20.0, 0.5, 1.0)


def servo_recording(servo: Servo, duration: float = 6.0) -> Recording:
    """A rotary direct drive under a PD position loop (10 Hz bandwidth, 0.7 damping) tracking
    three sines at f0, 2.3 f0 and 3.7 f0; noise-free. The friction's sign regularisation is
    the one the identification chooses for such a drive (``initial.Estimate.v_eps``)."""
    j = servo.inertia
    spec = DriveSpec(joint_type="hinge", mass=j, k_m=1.0, ctrl_limit=1e9, input_offset=0.0)
    v_eps = max(spec.v_eps, servo.coulomb * spec.timestep / (SLOPE_STEP * j))
    friction = StaticFriction(fc=servo.coulomb, fs=servo.coulomb, sigma=servo.viscous, v_eps=v_eps)
    model = load_model(build_drive(spec, JointParams(friction=friction)))
    d = mujoco.MjData(model)
    h = model.opt.timestep
    t = h * np.arange(int(round(duration / h)))
    ref = servo.amplitude * sum(np.sin(2 * np.pi * k * servo.f0 * t + k) for k in (1.0, 2.3, 3.7)) / 3
    w = 2 * np.pi * 10.0
    q, u = np.empty(len(t)), np.empty(len(t))
    for i in range(len(t)):
        q[i] = d.qpos[0]
        u[i] = j * w * w * (ref[i] - q[i]) - 1.4 * j * w * d.qvel[0]
        step_held(model, d, 0, u[i], u[i - 1] if i else 0.0, 1)
    return Recording(t=t, u=u, q=q, theta=q)


def geared_recording(k1: float, tau: bool = True, tip_mass: float = 1.0, chirp=None):
    """(Measured, ArmSpec): the shipped arm (rigid rod, no gravity, Coulomb + viscous motor
    friction 0.05 N m and 2e-4 N m s/rad, a linear gear of stiffness ``k1``, ``tip_mass`` [kg])
    under ``chirp`` (default an 80 -> 1 Hz ``Chirp``, through the gear's resonance) for 5 s,
    noise-free; ``tau=False`` drops the torque sensor."""
    from ..assets import ArmSpec
    from ..excitation import Chirp
    from ..identify.windows import Measured
    from ..physics.transmission import Transmission
    from ..sim import simulate
    arm = ArmSpec(segments=0, gravity=0.0, tip_mass=tip_mass)
    joint = JointParams(friction=StaticFriction(fc=0.05, fs=0.05, sigma=2e-4), load_friction=None,
                        transmission=Transmission(gear_ratio=160.0, k1=k1, k3=0.0, damping=1.0, hysteresis=None))
    trace = simulate((chirp or Chirp(f_start=80.0)).sample(1000, 5), arm=arm, joint=joint)
    rec = Recording(t=trace.t, u=trace.u, q=trace.q, theta=trace.theta, tau=trace.tau if tau else None)
    return Measured.from_recording(rec, 160.0), arm
