"""Measured windows next to the windowed predictions of one or more fitted models.

The windows tile the recording (each starts where the last ended, from the measured state, or
a warmup's worth earlier when that keeps its start off an input step), so their ``owned``
samples in order form one time line; predictions restart at every window start.
Everything the plots, the HTML page and the .rrd show comes from one ``Comparison``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..identify.structure import Structure
from ..identify.windows import Predictor

SIGNALS = ("q", "theta", "delta", "tau")  # what a window prediction holds, in display order
# Display unit and factor from SI per signal.
UNITS = {"q": ("rad", 1.0), "theta": ("deg", 180.0 / np.pi), "delta": ("mrad", 1e3), "tau": ("N m", 1.0)}
LABELS = {"q": "motor angle q", "theta": "link angle theta", "delta": "deflection delta",
          "tau": "transmission torque tau"}
ROTARY = ("rad", "rad/s", "N m")  # the units a plant may name otherwise (a slide: m, m/s, N)


@dataclass
class Comparison:
    """windows x samples arrays: measured, each model's prediction, and operating conditions."""

    t: np.ndarray                               # [s]
    measured: dict[str, np.ndarray]             # q, theta, delta and tau when recorded
    predicted: dict[str, dict[str, np.ndarray]]  # model label -> signal -> array
    conditions: dict[str, np.ndarray]           # qd, thetad, theta, q of the recording
    heldout: np.ndarray                         # bool per window
    cost: np.ndarray                            # bool per sample: used in the fit cost (after warmup)
    owned: np.ndarray                           # bool per window and sample: not in an earlier window
    plant_units: dict[str, str] = field(default_factory=dict)  # rotary unit -> the plant's (a slide's m, N)

    def unit(self, rotary: str) -> str:
        """The plant's own unit for a quantity given in rotary units."""
        return self.plant_units.get(rotary, rotary)

    def display(self, signal: str) -> tuple[str, float]:
        """Display unit and factor from SI of ``signal`` on this plant."""
        unit, factor = UNITS[signal]
        return self.unit(unit), factor

    @property
    def signals(self) -> tuple[str, ...]:
        return tuple(self.measured)

    def residual(self, label: str, signal: str) -> np.ndarray:
        """measured - predicted (windows x samples)."""
        return self.measured[signal] - self.predicted[label][signal]


def compare(predictor: Predictor, models: dict[str, Structure]) -> Comparison:
    """Predict every window with each model (one batched rollout per model signature)."""
    preds = predictor.predict(list(models.values()))
    m = predictor.m
    idx = predictor.samples
    measured = {s: np.asarray(v) for s, v in predictor.meas.items() if v is not None}
    measured = {s: measured[s] for s in SIGNALS if s in measured}
    cost = np.zeros(predictor.nwin_samples, bool)
    cost[predictor.cols[0]:] = True
    return Comparison(
        t=m.t[idx], measured=measured,
        # Every predicted signal, tau too where none was recorded: the loop plots show the models'.
        predicted={label: {s: p[s] for s in SIGNALS if s in p} for label, p in zip(models, preds)},
        conditions={k: v[idx] for k, v in (("q", m.q), ("theta", m.theta), ("qd", m.qd), ("thetad", m.thetad))
                    if v is not None},
        heldout=predictor.scored_holdout.copy(), cost=cost, owned=predictor.owned.copy(),
        plant_units=plant_units(next(iter(models.values())).nominal) if models else {})


def plant_units(plant) -> dict[str, str]:
    """The rotary units a plant names otherwise: a direct drive's ``unit`` (m and N on a slide)."""
    unit = getattr(plant, "unit", None)
    return {} if unit is None else {u: unit(u) for u in ROTARY if unit(u) != u}


def worst_signal(nrmse: dict[str, float], available) -> str:
    """The signal with the largest held-out NRMSE among those available (NaN counts as worst)."""
    options = [s for s in nrmse if s in available]
    return max(options, key=lambda s: np.inf if not np.isfinite(nrmse[s]) else nrmse[s])
