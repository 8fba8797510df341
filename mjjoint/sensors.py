"""The lab testbed's sensors (Sec. 4): a 15-bit motor resolver, a 20-bit link encoder, a noisy
torque cell. Simulated recordings (``benchmark.recorder``, ``design.record``) log through them."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

RESOLVER_BITS = 15      # motor resolver (Sec. 4)
LINK_ENCODER_BITS = 20  # output encoder (Sec. 4)


@dataclass(frozen=True)
class Sensors:
    resolver_bits: int = RESOLVER_BITS
    encoder_bits: int = LINK_ENCODER_BITS
    torque_noise: float = 0.05   # [N m] rms, contactless torque cell
    seed: int = 0


def lsb(bits: int) -> float:
    """One count of a ``bits``-bit encoder per revolution [rad]."""
    return 2 * math.pi / (1 << bits)


def quantise(x: np.ndarray, bits: int) -> np.ndarray:
    step = lsb(bits)
    return np.round(x / step) * step
