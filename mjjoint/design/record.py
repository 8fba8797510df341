"""A simulated recording of a known model under an open-loop programme, with the lab's sensors.

For checking designs (tests, ``scripts/bench_design.py``) and for the design itself (the noise
floor of a candidate input, ``response.input_floor``, and the rehearsed decision,
``rehearsal``): the model is simulated under u and its angles quantised as the testbed's
encoders do (``experiments.lab``), its torque cell noisy.
"""
from __future__ import annotations

import numpy as np

from ..rehearse.sensors import Sensors, quantise
from ..identify.structure import Structure
from ..recordings import Recording
from ..sim import Simulator, Trace


def logged(trace: Trace, sensors: Sensors = Sensors()) -> Recording:
    """A simulated run as the lab would log it (t, u, quantised q and theta, noisy tau)."""
    noise = np.random.default_rng(sensors.seed).normal(0.0, sensors.torque_noise, len(trace.t))
    return Recording(t=trace.t, u=trace.u, q=quantise(trace.q, sensors.resolver_bits),
                     theta=quantise(trace.theta, sensors.encoder_bits), tau=trace.tau + noise,
                     gear_ratio=trace.gear_ratio, meta={})


def record(truth: Structure, u: np.ndarray, rate: float, sensors: Sensors = Sensors()) -> Recording:
    """The truth's run under ``u`` as the lab would log it."""
    return logged(Simulator(truth.compile(), sample_rate=rate).run(u), sensors)
