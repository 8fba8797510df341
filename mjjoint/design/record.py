"""A simulated recording of a known truth under an open-loop programme, with the lab's sensors.

For checking designs (tests, ``scripts/bench_design.py``): the truth is simulated under u and
its angles quantised as the testbed's encoders do (``experiments.lab``), its torque cell noisy.
"""
from __future__ import annotations

import numpy as np

from ..rehearse.sensors import Sensors, quantise
from ..identify.structure import Structure
from ..recordings import Recording
from ..sim import Simulator


def record(truth: Structure, u: np.ndarray, rate: float, sensors: Sensors = Sensors()) -> Recording:
    """The truth's run under ``u`` as the lab would log it (t, u, quantised q and theta, noisy tau)."""
    trace = Simulator(truth.compile(), sample_rate=rate).run(u)
    noise = np.random.default_rng(sensors.seed).normal(0.0, sensors.torque_noise, len(trace.t))
    return Recording(t=trace.t, u=trace.u, q=quantise(trace.q, sensors.resolver_bits),
                     theta=quantise(trace.theta, sensors.encoder_bits), tau=trace.tau + noise,
                     gear_ratio=truth.gear_ratio, meta={})
