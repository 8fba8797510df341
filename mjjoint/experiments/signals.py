"""Signal-side helpers shared by the experiments: FRF from an impulse, loop areas, a lag.

Nothing here is joint physics: these are the measurement and input-shaping steps a lab
would apply to recorded (here: simulated) signals.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import find_peaks

from ..params import check


# Bins where the input spectrum falls below this fraction of its peak carry (near) no
# excitation: dividing by it amplifies leakage and rounding into spikes, so they are masked.
# A 1.5 ms rectangular pulse has its first zero at 667 Hz; -20 dB masks 614-725 Hz at 2 kHz.
INPUT_FLOOR = 0.1


def impulse_frf(u: np.ndarray, y: np.ndarray, sample_rate: float,
                floor: float = INPUT_FLOOR) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies [Hz] and Y(jw)/U(jw) from one record of input and response (same length).

    Bins where |U| < ``floor`` max|U| are NaN (no excitation there, so no estimate). The
    record must start at rest and be long enough for the response to have died out,
    otherwise the window truncation leaks into every bin.
    """
    u = np.asarray(u, float)
    y = np.asarray(y, float)
    if u.shape != y.shape or u.ndim != 1:
        raise ValueError(f"u and y must be 1-D and of equal length, got {u.shape} and {y.shape}")
    f = np.fft.rfftfreq(u.size, 1.0 / sample_rate)
    uf = np.fft.rfft(u)
    keep = excited(u, floor)
    h = np.full(f.shape, np.nan + 0j)
    h[keep] = np.fft.rfft(y)[keep] / uf[keep]
    return f, h


def excited(u: np.ndarray, floor: float = INPUT_FLOOR) -> np.ndarray:
    """The rfft bins of ``u`` holding at least ``floor`` times its peak magnitude."""
    check("floor", floor, 0.0, 1.0, hi_open=True)
    mag = np.abs(np.fft.rfft(np.asarray(u, float)))
    return mag >= max(floor * mag.max(), 1e-300)


def sampled_mass_line(f: np.ndarray, inertia: float, sample_rate: float) -> np.ndarray:
    """|W/U| of a free inertia, sampled: h / (2 J sin(w h / 2)) for a held input.

    It is 1/(w J) at low frequency and pi/2 times that at Nyquist (the integrator's
    discretisation), so a sampled FRF is compared with this line, not with 1/(w J).
    """
    h = 1.0 / sample_rate
    with np.errstate(divide="ignore"):
        return h / (2.0 * inertia * np.sin(np.pi * np.asarray(f, float) * h))


def extrema(f: np.ndarray, h: np.ndarray, prominence: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies of the resonances (local maxima of |h|) and anti-resonances (minima).

    Extrema must stand out by ``prominence`` in ln|h| (0.1: ~10 %); NaN bins are skipped.
    On a grid of spacing df a maximum sample lies within df of the true maximum.
    """
    keep = np.isfinite(h)
    f, mag = np.asarray(f)[keep], np.log(np.abs(np.asarray(h)[keep]))
    peaks = find_peaks(mag, prominence=prominence)[0]
    notches = find_peaks(-mag, prominence=prominence)[0]
    return f[peaks], f[notches]


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
