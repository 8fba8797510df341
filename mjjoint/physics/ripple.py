"""Position-periodic motor torque (cogging / eccentricity ripple), Sec. 2.1 (De Wit & Praly).

The chapter assumes no ripple; real motors show harmonics of the motor angle, so this is a
candidate term for diagnosis: r(q) = A sin(k q + phi) on the motor.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..params import check
from .jit import kernel


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
