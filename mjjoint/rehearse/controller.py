"""The position loop of a recording: PD or PID on the motor or the link angle, saturated.

It closes on the SENSED angle (``sensors``): quantised, noisy, late as the hardware's. The
velocity is the sensed angle's difference quotient through a first-order low-pass (an encoder
gives no velocity). The integral of a PID stops while the command is saturated and the error
would push it further (conditional integration), so a long saturation does not wind it up.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from ..params import check

KINDS = ("pd", "pid")
SIDES = ("motor", "link")
U_MAX = 1.3  # [N m] rated torque of the chapter's 400 W motor
# Default (kp, kd, ki) per side, for the shipped arm (160:1): on the motor ~15 Hz bandwidth; on
# the link, across the elastic gear, half the motor loop's bandwidth (kp 40 already rings);
# ki removes the offset gravity leaves within ~1 s.
GAINS = {"motor": (0.5, 7.5e-3, 2.0), "link": (20.0, 0.3, 20.0)}


@dataclass(frozen=True)
class Controller:
    """Gains in N m at the motor per rad (s) of the controlled angle: q on the motor, theta on the link."""

    kind: str = "pd"
    on: str = "motor"
    kp: float = 0.5           # [N m/rad] ~15 Hz bandwidth on the 5.7e-5 kg m^2 motor-side inertia
    kd: float = 7.5e-3        # [N m s/rad] damping ratio ~0.7
    ki: float = 0.0           # [N m/(rad s)] pid only
    velocity_cutoff: float = 200.0   # [Hz]
    u_max: float = U_MAX      # [N m] saturation of the command

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"controller {self.kind!r} is not known (allowed: {', '.join(KINDS)})")
        if self.on not in SIDES:
            raise ValueError(f"controller side {self.on!r} is not known (allowed: {', '.join(SIDES)})")
        for name in ("kp", "kd", "ki"):
            check(name, getattr(self, name), 0.0)
        if self.ki and self.kind != "pid":
            raise ValueError(f"ki={self.ki:g} needs the pid controller (a pd has no integral)")
        check("velocity_cutoff", self.velocity_cutoff, 0.0, lo_open=True)
        check("u_max", self.u_max, 0.0, lo_open=True)

    @classmethod
    def default(cls, kind: str = "pd", on: str = "motor", **settings) -> "Controller":
        """The side's default gains (``GAINS``; ki only for a pid), overridden by ``settings``."""
        if on not in GAINS:
            raise ValueError(f"controller side {on!r} is not known (allowed: {', '.join(SIDES)})")
        kp, kd, ki = GAINS[on]
        return cls(**{"kind": kind, "on": on, "kp": kp, "kd": kd, "ki": ki if kind == "pid" else 0.0, **settings})

    def describe(self) -> dict:
        return asdict(self)

    def law(self, rate: float) -> "ControlLaw":
        return ControlLaw(self, rate)


class ControlLaw:
    """``law(reference, sensed)`` -> the saturated command u [N m]; call once per sample."""

    def __init__(self, c: Controller, rate: float):
        self.c, self.rate = c, rate
        self.alpha = 1 - math.exp(-2 * math.pi * c.velocity_cutoff / rate)
        self.first, self.prev, self.v_filt, self.integral = True, 0.0, 0.0, 0.0

    def __call__(self, reference: float, y: float) -> float:
        c = self.c
        if not self.first:
            self.v_filt += self.alpha * ((y - self.prev) * self.rate - self.v_filt)
        self.first, self.prev = False, y
        e = reference - y
        u = c.kp * e - c.kd * self.v_filt
        if c.kind == "pid":
            trial = self.integral + e / self.rate
            pushed = u + c.ki * trial
            if abs(pushed) <= c.u_max or (pushed > 0) != (e > 0):
                self.integral = trial
            u += c.ki * self.integral
        return min(max(u, -c.u_max), c.u_max)
