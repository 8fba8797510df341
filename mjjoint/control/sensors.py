"""The measurements a real elastic joint gives its controller, per joint.

A motor resolver and a link encoder read angles in counts (``bits`` per revolution: the
lab's 15-bit resolver and 20-bit encoder, Sec. 4), a torque cell on the output shaft reads the
transmission torque with white noise, and the whole reading may arrive ``delay`` control steps
late (a fieldbus cycle). Noise is drawn from the task's ``random`` state, so an episode's
observations are a function of its seed.
"""
from __future__ import annotations

from collections import OrderedDict, deque
from dataclasses import dataclass

import numpy as np

from ..rehearse.sensors import LINK_ENCODER_BITS, RESOLVER_BITS, quantise
from ..params import check
from .physics import JointPhysics


def _bits(name: str, value: int | None) -> None:
    if value is not None and (int(value) != value or not 1 <= value <= 32):
        raise ValueError(f"{name}={value!r} is outside the allowed range [1, 32] (integer, or None for exact)")


@dataclass(frozen=True)
class JointSensors:
    """Resolutions [bits per revolution; None reads exactly], torque-cell noise, delay."""

    resolver_bits: int | None = RESOLVER_BITS      # motor side, per motor revolution
    encoder_bits: int | None = LINK_ENCODER_BITS   # link side, per link revolution
    torque_noise: float = 0.05                     # [N m] rms, as the benchmark's torque cell
    delay: int = 0                                 # [control steps] until a reading arrives

    def __post_init__(self) -> None:
        _bits("resolver_bits", self.resolver_bits)
        _bits("encoder_bits", self.encoder_bits)
        check("torque_noise", self.torque_noise, 0.0, 1e3)
        if int(self.delay) != self.delay or not 0 <= self.delay <= 1000:
            raise ValueError(f"delay={self.delay!r} is outside the allowed range [0, 1000] (integer control steps)")


class SensorReadout:
    """One episode's readings of ``JointSensors``: sampled once per physics time, delivered
    ``delay`` samples late (the first reading stands in for those before it)."""

    def __init__(self, sensors: JointSensors) -> None:
        self.sensors = sensors
        self._queue: deque[OrderedDict] = deque()
        self._time = None

    def clear(self) -> None:
        self._queue.clear()
        self._time = None

    def read(self, physics: JointPhysics, random: np.random.RandomState) -> OrderedDict:
        # Observations may be asked for more than once per step: sample only when time moved.
        if self._time != physics.time():
            self._time = physics.time()
            reading = self._sample(physics, random)
            if not self._queue:
                self._queue.extend([reading] * self.sensors.delay)
            self._queue.append(reading)
            while len(self._queue) > self.sensors.delay + 1:
                self._queue.popleft()
        return OrderedDict((k, v.copy()) for k, v in self._queue[0].items())

    def _sample(self, physics: JointPhysics, random: np.random.RandomState) -> OrderedDict:
        s = self.sensors
        q, theta = physics.motor_angles(), physics.link_angles()
        torque = physics.transmission_torques()
        return OrderedDict(
            motor_angle=q if s.resolver_bits is None else quantise(q, s.resolver_bits),
            link_angle=theta if s.encoder_bits is None else quantise(theta, s.encoder_bits),
            joint_torque=torque + s.torque_noise * random.standard_normal(torque.shape),
        )
