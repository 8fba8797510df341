"""The design criterion: the expected log-likelihood ratio between two rivals' predictions.

With each measured sample y_s(t) Gaussian about rival A's prediction, of variance
S_s(t) = sigma_s^2 (the measurement noise) + v_A,s(t) + v_B,s(t) (each rival's prediction
variance from its parameter uncertainty), the log-likelihood ratio of A over B has the
expectation

    D_A = 1/2 sum_s sum_t (y_A,s(t) - y_B,s(t))^2 / S_s(t)

when A is true. The predictions are the windowed ones the decision compares
(``response.windowed``), in A's run for D_A and in B's for D_B; D is their mean
(docs/design-experiments.md). D in nats: D = 3 makes the true rival 20 times as likely.
Where the rivals differ by less than their combined spread, a sample counts little however
large the difference.
"""
from __future__ import annotations

import numpy as np

from ..identify.windows import noise_std
from .response import Windowed

# The user's signal -> the windowed prediction's: theta is compared as the deflection
# delta = q / N - theta, as the fits do.
PREDICTED = {"q": "q", "theta": "delta", "tau": "tau"}


def noise_floor(columns: dict[str, np.ndarray | None], rate: float) -> dict[str, float]:
    """Measurement noise std of each recorded signal (q, theta, tau), estimated from a recording
    as its robust spread about a Savitzky-Golay smoothing (``windows.noise_std``)."""
    return {s: noise_std(np.asarray(x, float), rate) for s, x in columns.items() if x is not None}


def predicted_noise(noise: dict[str, float], gear_ratio: float) -> dict[str, float]:
    """The noise std of the predicted signals: delta's from theta's and q's (independent)."""
    out = {"q": noise["q"], "tau": noise.get("tau", 0.0)}
    out["delta"] = float(np.hypot(noise.get("theta", 0.0), noise["q"] / gear_ratio))
    return out


def separation(w: Windowed, noise: dict[str, float], signals, gear_ratio: float) -> dict[str, np.ndarray]:
    """Per signal and cost sample, (y_A - y_B)^2 / S: the squared difference in combined spreads."""
    floor = predicted_noise(noise, gear_ratio)
    out = {}
    for user in signals:
        s = PREDICTED[user]
        a, b = w.mean[0][s], w.mean[1][s]
        spread = max(floor[s], 1e-12) ** 2 + w.var[0][s] + w.var[1][s]
        out[user] = np.nan_to_num((a - b) ** 2 / spread, nan=0.0)
    return out


def discrimination(ws: list[Windowed], noise: dict[str, float], signals, gear_ratio: float) -> float:
    """D: the expected log-likelihood ratio between the rivals [nats], averaged over which is true."""
    return float(np.mean([0.5 * sum(v.sum() for v in separation(w, noise, signals, gear_ratio).values())
                          for w in ws]))
