"""Generic torques of a documented form at the motor or the link: what the diagnosis fits where
a located residual has a structure that no catalogued effect explains (``identify.generic``).

Each is an additive term (``physics.term``) whose torque is a sum of basis forms of one
coordinate:

    link:   tau_L = c0 + c1 theta + a sin(k theta) + b cos(k theta)
    motor:  tau_m = a sin(k q) + b cos(k q) + sgn_eps(q') (f_a sin(k q) + f_b cos(k q))

k is a real number of cycles per revolution (the period is estimated from the data, not assumed
to be a harmonic); the motor's last pair is a friction level that varies with the angle.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..params import check
from .jit import kernel
from .stribeck import smooth_sign
from .term import Term

MAX_CYCLES = 400.0  # cycles per revolution a periodic form may have


def _check_form(form, amplitudes: tuple[str, ...]) -> None:
    """Amplitudes finite, cycles in (0, MAX_CYCLES]."""
    for name in amplitudes:
        check(name, getattr(form, name))
    check("cycles", form.cycles, 0.0, MAX_CYCLES, lo_open=True)


@dataclass(frozen=True)
class LinkForm:
    """Generic link torque [N m]: constant, linear in theta [N m/rad], periodic in theta."""

    constant: float = 0.0
    linear: float = 0.0
    sin: float = 0.0
    cos: float = 0.0
    cycles: float = 1.0     # k, cycles per link revolution

    def __post_init__(self) -> None:
        _check_form(self, ("constant", "linear", "sin", "cos"))


@dataclass(frozen=True)
class MotorForm:
    """Generic motor torque [N m]: periodic in q, and a friction level periodic in q."""

    sin: float = 0.0
    cos: float = 0.0
    friction_sin: float = 0.0
    friction_cos: float = 0.0
    cycles: float = 1.0     # k, cycles per motor revolution
    v_eps: float = 1.0      # [rad/s] regularisation of the friction's sign, as StaticFriction's

    def __post_init__(self) -> None:
        _check_form(self, ("sin", "cos", "friction_sin", "friction_cos"))
        check("v_eps", self.v_eps, 0.0, lo_open=True)


@kernel
def link_form_torque(blk, o, st, s, q, wq, theta, wtheta):
    """The generalised forces (motor, link) of ``LinkForm``."""
    x = blk[o + L.cycles] * theta
    return 0.0, (blk[o + L.constant] + blk[o + L.linear] * theta
                 + blk[o + L.sin] * math.sin(x) + blk[o + L.cos] * math.cos(x))


@kernel
def motor_form_torque(blk, o, st, s, q, wq, theta, wtheta):
    """The generalised forces (motor, link) of ``MotorForm``: the friction part opposes q'."""
    x = blk[o + M.cycles] * q
    sx, cx = math.sin(x), math.cos(x)
    level = blk[o + M.friction_sin] * sx + blk[o + M.friction_cos] * cx
    return blk[o + M.sin] * sx + blk[o + M.cos] * cx - smooth_sign(wq, blk[o + M.v_eps]) * level, 0.0


LINK_TERM = Term(section="link_form", kinds={"series": LinkForm}, site="link",
                 doc="generic link torque: constant, linear and periodic in theta", torque=link_form_torque,
                 default_on=False)
MOTOR_TERM = Term(section="motor_form", kinds={"series": MotorForm}, site="motor",
                  doc="generic motor torque and friction level, periodic in q", torque=motor_form_torque,
                  default_on=False)
L, M = LINK_TERM.offsets, MOTOR_TERM.offsets
