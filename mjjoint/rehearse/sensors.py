"""Sensor models of a recording: encoder quantisation, additive noise, a delay in samples.

A reading is what an acquisition system logs: the angles as whole encoder counts (noise, if
any, acts before the counter, so the logged angle stays on the count grid), the torque cell
with additive noise, and all three ``delay`` samples late. Readings are taken once per sample,
in order, from one random generator per ``seed``: the same sensors and seed give the same bytes.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import asdict, dataclass

import numpy as np

from ..params import check

RESOLVER_BITS = 15      # motor resolver of the chapter's testbed (Sec. 4)
LINK_ENCODER_BITS = 20  # its output encoder (Sec. 4)
MAX_BITS = 32
# Beyond these no sensor is described: an angle's noise of a radian rms, a torque cell's of
# 10 kN m rms (the largest robot axes carry a few kN m).
MAX_ANGLE_NOISE = 1.0   # [rad]
MAX_TORQUE_NOISE = 1e4  # [N m]


def lsb(bits: int) -> float:
    """One count of a ``bits``-bit encoder per revolution [rad]."""
    return 2 * math.pi / (1 << bits)


def quantise(x: np.ndarray, bits: int) -> np.ndarray:
    """``x`` [rad] as whole counts of a ``bits``-bit encoder; ``bits`` 0 is an ideal sensor."""
    if bits == 0:
        return x
    step = lsb(bits)
    return np.round(x / step) * step


def _check_int(name: str, value, lo: int, hi: int) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name}={value!r} must be an integer in [{lo}, {hi}]")
    check(name, value, lo, hi)


@dataclass(frozen=True)
class Sensors:
    """Motor resolver, link encoder, torque cell: resolution, noise (rms, SI), delay, seed."""

    resolver_bits: int = RESOLVER_BITS     # counts of q per revolution = 2**bits; 0: ideal
    encoder_bits: int = LINK_ENCODER_BITS  # counts of theta per revolution; 0: ideal
    q_noise: float = 0.0                   # [rad] rms, before the counter
    theta_noise: float = 0.0               # [rad] rms, before the counter
    torque_noise: float = 0.05             # [N m] rms, contactless torque cell
    delay: int = 0                         # [samples] from the plant to the logged (and fed back) value
    seed: int = 0

    def __post_init__(self) -> None:
        _check_int("resolver_bits", self.resolver_bits, 0, MAX_BITS)
        _check_int("encoder_bits", self.encoder_bits, 0, MAX_BITS)
        for name in ("q_noise", "theta_noise"):
            check(name, getattr(self, name), 0.0, MAX_ANGLE_NOISE)
        check("torque_noise", self.torque_noise, 0.0, MAX_TORQUE_NOISE)
        _check_int("delay", self.delay, 0, 10_000)
        _check_int("seed", self.seed, 0, 2 ** 63 - 1)

    def describe(self) -> dict:
        """JSON-ready description, with each encoder's count in rad."""
        return {**asdict(self), "resolver_lsb": lsb(self.resolver_bits) if self.resolver_bits else 0.0,
                "encoder_lsb": lsb(self.encoder_bits) if self.encoder_bits else 0.0}

    def reader(self) -> "SensorReader":
        return SensorReader(self)


class SensorReader:
    """``reader(q, theta, tau)`` -> the logged (q, theta, tau) of this sample; call once per sample."""

    def __init__(self, sensors: Sensors):
        self.s = sensors
        self.rng = np.random.default_rng(sensors.seed)
        self.queue: deque[tuple[float, float, float]] = deque()

    def _noise(self, rms: float) -> float:
        # No draw for a noiseless channel: adding a channel's noise leaves the others' draws alone.
        return self.rng.normal(0.0, rms) if rms else 0.0

    def __call__(self, q: float, theta: float, tau: float) -> tuple[float, float, float]:
        s = self.s
        reading = (quantise(np.array(q + self._noise(s.q_noise)), s.resolver_bits).item(),
                   quantise(np.array(theta + self._noise(s.theta_noise)), s.encoder_bits).item(),
                   tau + self._noise(s.torque_noise))
        self.queue.append(reading)
        if len(self.queue) > s.delay + 1:
            self.queue.popleft()
        return self.queue[0]  # until the line fills, the first reading is repeated
