"""The arm's joint linearised about an operating deflection: Eq. (3) behind a gear.

Reflected to the link side through the gear ratio N, the rotor J and its viscous friction
sigma become m = J N^2 and d = sigma N^2, the motor torque N u, the motor angle q/N. The
transmission is its tangent stiffness at the operating deflection delta0,

    K = k1 + 2 k2 |delta0| + 3 k3 delta0^2,

with its damping D as the spring's damper c; the link is the inertia M the hinge carries
(the MjModel's mass matrix) with the bearing's viscous d_f. So the motor velocity per motor
torque is W/U = N^2 s q(s)/U(s) of ``LinearJoint.motor_transfer``: free, a resonance at
sqrt(K (1/m + 1/M)) above an anti-resonance at sqrt(K/M); locked, the rotor on the spring,
sqrt(K/m).

Exactly linear is only a joint without the chapter's nonlinear terms, ``LINEAR_JOINT`` on
``RIGID_ARM``: viscous motor friction (2SEP's sigma, no Coulomb or pre-sliding), no
hysteresis, bearing friction without Coulomb, a rigid rod (no bending modes) and no gravity
(a hanging link adds the pendulum stiffness m l g). The k3 hardening stays, so the
prestressed joint is stiffer; the pulse must be small enough to keep the twist near delta0.
"""
from __future__ import annotations

import mujoco
import numpy as np
from scipy import signal

from ..assets.builder import ArmSpec
from ..joint import JointParams
from ..physics.load import LoadFriction
from ..physics.stribeck import StaticFriction
from ..physics.transmission import Transmission
from ..physics.twosep import TwoSEP
from .linear_joint import LinearJoint

LINEAR_JOINT = JointParams(friction=StaticFriction.viscous(TwoSEP().sigma),
                           transmission=Transmission(hysteresis=None),
                           load_friction=LoadFriction(fc=0.0))
RIGID_ARM = ArmSpec(segments=0, gravity=0.0)


def tangent_stiffness(transmission: Transmission, delta: float) -> float:
    """dGamma/d delta of the elastic stiffness polynomial at deflection ``delta`` [N m/rad]."""
    d = abs(delta)
    return transmission.k1 + 2 * transmission.k2 * d + 3 * transmission.k3 * d * d


def hinge_inertia(model: mujoco.MjModel, joint: str) -> float:
    """Inertia about hinge ``joint`` of everything it carries, at qpos0 [kg m^2]."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    dof = model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)]
    return float(full[dof, dof])


def linearise(model: mujoco.MjModel, joint: JointParams) -> LinearJoint:
    """Eq. (3) on the link side for a model of ``joint`` (free output); K is the caller's."""
    f, lf, tr = joint.friction, joint.load_friction, joint.transmission
    if not (isinstance(f, StaticFriction) and f.fc == 0 and f.fs == 0 and f.sigma > 0):
        raise ValueError(f"friction={f!r} is not linear: use StaticFriction.viscous(sigma), sigma > 0")
    if lf is None or lf.fc != 0 or lf.viscous <= 0:
        raise ValueError(f"load_friction={lf!r} is not linear: use LoadFriction(fc=0, viscous > 0)")
    if tr is None or tr.hysteresis is not None or tr.backlash != 0:
        raise ValueError(f"transmission={tr!r} is not elastic: use hysteresis=None, backlash=0")
    n2 = tr.gear_ratio ** 2
    return LinearJoint(m=hinge_inertia(model, joint.motor_joint) * n2, M=hinge_inertia(model, joint.link_joint),
                       d=f.sigma * n2, D=lf.viscous, c=tr.damping)


def motor_mobility(lj: LinearJoint, K: float, gear_ratio: float, f: np.ndarray,
                   locked: bool = False) -> np.ndarray:
    """W/U [rad/s/(N m)] of the motor at frequencies ``f`` [Hz], motor side."""
    w = 2 * np.pi * np.asarray(f, float)
    _, q = signal.freqresp(lj.motor_transfer(K, locked), w)
    return gear_ratio ** 2 * 1j * w * q


def natural_frequencies(lj: LinearJoint, K: float) -> dict[str, float]:
    """Undamped resonance and anti-resonance [Hz] of the free joint and the locked one's."""
    return {"free resonance": np.sqrt(K * (1 / lj.m + 1 / lj.M)) / (2 * np.pi),
            "free anti-resonance": np.sqrt(K / lj.M) / (2 * np.pi),
            "locked resonance": np.sqrt(K / lj.m) / (2 * np.pi)}
