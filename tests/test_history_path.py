"""The motor-angle path 2SEP's window-start history runs along (identify/windows.py).

A resting motor's quantised encoder toggles between two counts; a derivative of that chatter
crosses zero again and again, and every crossing is a reversal to 2SEP (its pre-sliding memory
restarts). The path removes retraces within the angle's noise band and keeps real ones.
"""
from __future__ import annotations

import math

import numpy as np

from mjjoint.identify.windows import Measured

RATE = 1000.0
LSB = 2 * math.pi / 2 ** 15  # 15-bit resolver


def _measured(q: np.ndarray) -> Measured:
    t = np.arange(q.size) / RATE
    zero = np.zeros_like(q)
    return Measured(t=t, u=zero, q=q, theta=None, tau=None, qd=zero, thetad=None, gear_ratio=1.0, rate=RATE)


def _reversals(x: np.ndarray) -> int:
    s = np.sign(np.diff(x))
    s = s[s != 0]
    return int(np.sum(s[1:] != s[:-1]))


def test_noise_estimate_is_the_quantisation_noise():
    t = np.arange(20000) / RATE
    q = np.round((3.0 * np.sin(2 * np.pi * 0.7 * t) + 0.4 * np.sin(2 * np.pi * 9.0 * t)) / LSB) * LSB
    assert abs(_measured(q).q_noise / (LSB / math.sqrt(12)) - 1) < 0.2


def test_chatter_at_rest_is_no_reversal_and_real_reversals_are_kept():
    rng = np.random.default_rng(0)
    t = np.arange(6000) / RATE
    # Slow swings (two reversals), then rest half-way between two counts, where the encoder
    # toggles between them with the noise.
    moving = 0.02 * np.sin(2 * np.pi * 0.5 * t[:3000])  # 0.02 rad: ~100 counts
    rest = np.full(3000, (np.floor(moving[-1] / LSB) + 0.5) * LSB) + rng.normal(0.0, 0.15 * LSB, 3000)
    q = np.round(np.concatenate([moving, rest]) / LSB) * LSB
    assert _reversals(q[3000:]) > 50  # the raw angle chatters
    m = _measured(q)
    path = m.q_path
    assert _reversals(path[3000:]) == 0
    true = _reversals(np.concatenate([moving, np.full(3000, moving[-1])]))
    assert _reversals(path) == true
    assert np.max(np.abs(path - q)) <= 3.0 * m.q_noise + 1e-12  # within the band (REVERSAL_BAND)
