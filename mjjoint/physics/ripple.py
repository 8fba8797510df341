"""Position-periodic motor torque (cogging / eccentricity ripple), Sec. 2.1 (De Wit & Praly).

The chapter assumes no ripple; real motors show harmonics of the motor angle, so this is a
candidate term for diagnosis: r(q) = A sin(k q + phi) on the motor.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..params import check
from .jit import kernel
from .term import Term


@kernel
def ripple_torque(q: float, amplitude: float, harmonic: float, phase: float) -> float:
    return amplitude * math.sin(harmonic * q + phase)


@dataclass(frozen=True)
class TorqueRipple:
    """A k-per-revolution sinusoidal torque on the motor [N·m]."""

    amplitude: float = 0.02  # [N·m]: ~1.5 % of a 400 W motor's ~1.3 N·m rated torque
    harmonic: float = 6.0    # cycles per motor revolution: 6 = 3 pole pairs (BLDC typical)
    phase: float = 0.0       # [rad]

    def __post_init__(self) -> None:
        check("amplitude", self.amplitude, 0.0)
        check("harmonic", self.harmonic, 1.0, 200.0)
        if float(self.harmonic) != int(self.harmonic):
            raise ValueError(f"harmonic={self.harmonic!r} must be an integer in [1, 200]")
        check("phase", self.phase, -math.pi, math.pi)


@kernel
def ripple_site_torque(blk, o, st, s, q, wq, theta, wtheta):
    """The term's generalised forces (motor, link): the ripple on the rotor."""
    return ripple_torque(q, blk[o + P.amplitude], blk[o + P.harmonic], blk[o + P.phase]), 0.0


# The chapter assumes no ripple: absent unless the MJCF names it.
TERM = Term(section="ripple", kinds={"sine": TorqueRipple}, site="motor",
            doc="position-periodic motor torque (cogging, eccentricity)", torque=ripple_site_torque,
            default_on=False)
P = TERM.offsets
