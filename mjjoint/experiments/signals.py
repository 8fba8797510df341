"""Signal-side helpers shared by the experiments: FRF from an impulse, loop areas, a lag.

Nothing here is joint physics: these are the measurement and input-shaping steps a lab
would apply to recorded (here: simulated) signals.
"""
from __future__ import annotations

import numpy as np

from ..params import check


def impulse_frf(u: np.ndarray, y: np.ndarray, sample_rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies [Hz] and Y(jw)/U(jw) from one record of input and response (same length).

    The record must start at rest and be long enough for the response to have died out,
    otherwise the window truncation leaks into every bin.
    """
    u = np.asarray(u, float)
    y = np.asarray(y, float)
    if u.shape != y.shape or u.ndim != 1:
        raise ValueError(f"u and y must be 1-D and of equal length, got {u.shape} and {y.shape}")
    f = np.fft.rfftfreq(u.size, 1.0 / sample_rate)
    uf = np.fft.rfft(u)
    if np.any(np.abs(uf) < 1e-12 * np.abs(uf).max()):
        raise ValueError("the input spectrum has zeros: use a shorter pulse than the sample period allows")
    return f, np.fft.rfft(y) / uf


def loop_area(x: np.ndarray, y: np.ndarray) -> float:
    """Area enclosed by the closed curve (x, y) (shoelace; counter-clockwise positive)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def first_order_lag(u: np.ndarray, cutoff: float, sample_rate: float) -> np.ndarray:
    """u through 1/(s/cutoff + 1), exact for a zero-order-held input (the Simulator's hold)."""
    check("cutoff", cutoff, 0.0, lo_open=True)
    a = np.exp(-cutoff / sample_rate)
    out = np.empty(len(u))
    y = 0.0
    for k, uk in enumerate(np.asarray(u, float)):
        out[k] = y          # the lag's output at t_k, held by the simulator over [t_k, t_k+1)
        y = a * y + (1.0 - a) * uk
    return out
