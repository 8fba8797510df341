"""Operating conditions of an elastic joint, computed from measured signals.

The locate step asks under which condition a residual concentrates; these arrays are the
candidate conditions, one value per sample. Derivatives use Savitzky-Golay filters (a local
polynomial fit over ~10 ms) because finite differences of quantized encoder angles are mostly
quantization noise.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import savgol_filter

from ..recordings.rates import savgol_rate

SAVGOL_WINDOW_S = 0.010   # [s]: long enough to average encoder steps, short next to joint dynamics
SAVGOL_POLYORDER = 2      # quadratic: follows turning points without the noise gain of higher orders
REVERSAL_SWING = 0.05     # a reversal must swing qd past ±5 % of its 95th-percentile speed


def sample_period(t: np.ndarray) -> float:
    """Sample period [s] of a strictly increasing, uniformly sampled time base."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError("t must be a 1-D array with at least two samples")
    steps = np.diff(t)
    dt = float(np.median(steps))
    # Filters and spectra below assume one sample period; 10 % jitter is tolerated, gaps are not.
    if not dt > 0 or np.any(steps <= 0) or np.max(np.abs(steps - dt)) > 0.1 * dt:
        raise ValueError("t must be strictly increasing and uniformly sampled; resample first")
    return dt


def _savgol_window(dt: float, n: int) -> int:
    width = max(int(round(SAVGOL_WINDOW_S / dt)), SAVGOL_POLYORDER + 2)
    width += 1 - width % 2  # savgol_filter needs an odd window
    if width > n:
        raise ValueError(f"record of {n} samples is shorter than the {width}-sample smoothing window")
    return width


def reversal_proximity(t: np.ndarray, qd: np.ndarray, min_swing: float | None = None) -> np.ndarray:
    """Time [s] from each sample to the nearest motor velocity reversal (inf if there is none).

    A reversal counts only when qd goes from beyond +min_swing to beyond -min_swing or back
    (default: REVERSAL_SWING of the 95th-percentile |qd|), so noise chattering around zero
    during a dwell is one reversal, not many. Its time is the middle of the zero crossings
    between the two excursions.
    """
    t = np.asarray(t, dtype=float)
    qd = np.asarray(qd, dtype=float)
    if min_swing is None:
        min_swing = REVERSAL_SWING * float(np.percentile(np.abs(qd), 95))
    beyond = np.flatnonzero(np.abs(qd) > min_swing)
    side = np.sign(qd[beyond])
    flips = np.flatnonzero(side[1:] != side[:-1])
    times = []
    for a, b in zip(beyond[flips], beyond[flips + 1]):
        seg = qd[a:b + 1]
        j = np.flatnonzero((seg[:-1] > 0) != (seg[1:] > 0)) + a
        crossings = t[j] + (t[j + 1] - t[j]) * qd[j] / (qd[j] - qd[j + 1])
        times.append(0.5 * (crossings[0] + crossings[-1]))
    if not times:
        return np.full(t.shape, np.inf)
    times = np.asarray(times)
    after = np.searchsorted(times, t)
    before = np.clip(after - 1, 0, times.size - 1)
    after = np.clip(after, 0, times.size - 1)
    return np.minimum(np.abs(t - times[before]), np.abs(t - times[after]))


def operating_conditions(
    t: np.ndarray,
    q: np.ndarray,
    theta: np.ndarray | None,
    u: np.ndarray,
    gear_ratio: float,
    tau: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Per-sample operating conditions from measured motor angle q, link angle theta [rad],
    motor torque u and optionally transmission torque tau.

    Keys: qd [rad/s]; qdd [rad/s^2]; q and q_mod = q mod 2pi [rad] (for position-periodic effects);
    reversal_proximity [s]; u, and tau when given, passed through; ud, u's rate. With theta (None for a
    direct drive, which has no output side) also: thetad [rad/s]; accel (link acceleration);
    delta = q/N - theta, abs_delta [rad]; delta_d [rad/s]; sin_theta, cos_theta; theta [rad].
    """
    dt = sample_period(t)
    signals = {"q": q, "u": u} | ({} if theta is None else {"theta": theta}) | ({} if tau is None else {"tau": tau})
    arrays = {k: np.asarray(v, dtype=float) for k, v in signals.items()}
    for name, a in arrays.items():
        if a.shape != np.shape(t):
            raise ValueError(f"{name} has shape {a.shape}, expected {np.shape(t)} like t")
    if not gear_ratio > 0:
        raise ValueError(f"gear_ratio={gear_ratio!r} must be positive")
    q = arrays["q"]
    width = _savgol_window(dt, q.size)

    def smooth(x: np.ndarray, deriv: int = 0) -> np.ndarray:
        if deriv:
            return savgol_rate(x, width, SAVGOL_POLYORDER, dt)
        return savgol_filter(x, width, SAVGOL_POLYORDER, delta=dt)

    qd = smooth(q, 1)
    out = {
        "qd": qd,
        # Differentiating the smoothed velocity again smooths twice, which acceleration needs.
        "qdd": smooth(qd, 1),
        "q": q,
        "q_mod": np.mod(q, 2.0 * np.pi),
        "reversal_proximity": reversal_proximity(t, qd),
        "u": arrays["u"],
        "ud": smooth(arrays["u"], 1),
    }
    if theta is not None:
        theta = arrays["theta"]
        thetad = smooth(theta, 1)
        # Smoothed too, so that "small |delta|" is not decided by quantization steps around zero.
        delta = smooth(q / gear_ratio - theta)
        out |= {"thetad": thetad, "accel": smooth(thetad, 1), "delta": delta, "abs_delta": np.abs(delta),
                "delta_d": qd / gear_ratio - thetad, "sin_theta": np.sin(theta), "cos_theta": np.cos(theta),
                "theta": theta}
    if tau is not None:
        out["tau"] = arrays["tau"]
    return out
