"""Rates of sampled signals: Savitzky-Golay derivatives that read a rest as a rate of zero.

On a constant stretch a derivative filter returns its rounding, about eps |x| / dt, whose sign
the linear algebra that computed the filter's coefficients decides (OpenBLAS's kernels differ).
That sign would pass for a motion's direction (a Coulomb term's sgn(q'), a reversal), so rates
far below |x| / dt are read as exactly zero.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import savgol_filter

ROUND_OFF = 1e-12  # a rate below this share of max |x| / dt is the filter's rounding


def savgol_rate(x: np.ndarray, width: int, order: int, dt: float) -> np.ndarray:
    """The first derivative of ``x`` sampled every ``dt`` [s]: a centred polynomial of ``order``
    over ``width`` samples (scipy's ``savgol_filter``), its rounding on rests set to zero."""
    y = savgol_filter(x, width, order, deriv=1, delta=dt)
    y[np.abs(y) <= ROUND_OFF * np.max(np.abs(x), initial=0.0) / dt] = 0.0
    return y
