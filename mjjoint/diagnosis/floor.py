"""The noise floor of a recording: how closely the right model could predict it.

A verdict is a claim about the final model's held-out misfit, so it is judged against what a
correct model would still miss on this very recording, per signal, in the NRMSE the fits
report (rms error over the signal's spread within the held-out windows):

- **measurement noise**: the white part of each recorded signal (its robust spread about a
  smoothing, ``windows.noise_std``), and at least its quantisation (the common step of its
  values, step / sqrt(12));
- **the windowing**: a noisy twin of the recording made by the final model itself
  (``identify.twin``: its run under the measured input, read through the recording's sensors),
  predicted by the same model in the same windows, over TWIN_DRAWS draws of the noise. Its
  misfit is what window starts reconstructed from noisy samples and hidden states (pre-sliding,
  lag, hysteresis) cost a model that is right, as a share of the twin's own spread. A twin
  that wanders into another regime than the recording's gives none (``twin.TWIN_SPREAD``), and
  so does a twin its model predicts no better than the signal's mean (NRMSE 1 or more): the
  floor is then the noise's alone, and the verdict the stricter for it;
- **resolution**: ``RESOLUTION`` of the spread, below which integration and interpolation
  differences between any two implementations of the same physics dominate.

The floor of a signal is the largest of the three, but for the windowing's share: that comes from
the model under judgement, not from the recording (a model that lacks physics can have a twin that
its windows' starts cost more), so it counts up to ``WINDOWING_TRUST`` times what the recording
alone sets (measurement noise, at least the resolution). The model explains the recording when
every signal's held-out NRMSE is within ``EXPLAINED_RATIO`` of its floor. The absolute gain an
effect must reach (``Floor.cost``) keeps the twin's whole misfit: it is the scale of what a right
model still misses, not a claim.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..identify.fit import FitResult
from ..identify.structure import Structure
from ..identify.twin import Twin, sensors
from ..identify.windows import Predictor

RESOLUTION = 0.01      # NRMSE no model comparison resolves below (module doc)
EXPLAINED_RATIO = 1.5  # held-out NRMSE up to this multiple of the floor: within the noise
# The twin's windowing floor counts up to this multiple of the recording's own (module doc).
WINDOWING_TRUST = 2.0
# Noise draws a twin's floor averages: with a few held-out windows, one draw's floor moves by
# half its value from draw to draw.
TWIN_DRAWS = 4


@dataclass(frozen=True)
class Floor:
    """Per signal: noise std and quantisation step [signal units], the floors as NRMSE."""

    noise: dict[str, float]
    quantum: dict[str, float]
    measurement: dict[str, float]       # NRMSE of the measurement noise alone
    twin: dict[str, float]              # NRMSE of the right model on its noisy twin (may be empty)
    note: str = ""                      # why the twin is missing, if it is
    signals: tuple[str, ...] = field(default=())
    scored: tuple[str, ...] = field(default=())  # those the fit's cost scores (default: every one)

    @property
    def recorded(self) -> dict[str, float]:
        """What the recording alone sets: its measurement noise, at least the resolution."""
        return {s: max(self.measurement[s], RESOLUTION) for s in self.signals}

    @property
    def nrmse(self) -> dict[str, float]:
        """The floor of each signal (module doc): the twin's misfit counted up to WINDOWING_TRUST
        times what the recording sets."""
        return {s: max(r, min(self.twin.get(s, 0.0), WINDOWING_TRUST * r)) for s, r in self.recorded.items()}

    @property
    def capped(self) -> tuple[str, ...]:
        """The signals whose twin misses by more than the floor counts."""
        floor = self.nrmse
        return tuple(s for s in self.signals if self.twin.get(s, 0.0) > floor[s])

    def ratios(self, nrmse: dict[str, float]) -> dict[str, float]:
        """Each signal's held-out NRMSE over its floor (inf where the prediction failed)."""
        floor = self.nrmse
        return {s: (float(nrmse[s]) / floor[s] if np.isfinite(nrmse[s]) else np.inf) for s in self.signals}

    def worst(self, nrmse: dict[str, float]) -> float:
        """The largest of ``ratios``: how far the model is from the floor where it misses most."""
        return max(self.ratios(nrmse).values())

    def explained(self, nrmse: dict[str, float]) -> bool:
        return all(r <= EXPLAINED_RATIO for r in self.ratios(nrmse).values())

    def cost(self) -> float:
        """The floor in the fit's cost units: the mean squared normalised residual over the
        signals the cost scores (a signal reported but not scored, a deflection far above its
        floor, would otherwise set the absolute gain an effect must reach on the others)."""
        recorded = self.recorded
        return float(np.mean([max(recorded[s], self.twin.get(s, 0.0)) ** 2 for s in (self.scored or self.signals)]))

    def as_dict(self) -> dict:
        return {"nrmse": self.nrmse, "measurement_nrmse": self.measurement, "twin_nrmse": self.twin,
                "noise_std": self.noise, "quantisation_step": self.quantum,
                "explained_ratio": EXPLAINED_RATIO, "windowing_trust": WINDOWING_TRUST, "resolution": RESOLUTION, **({"note": self.note} if self.note else {})}


UNEXPLAINED_INTERVALS = ("the model misses the recording above its noise floor: its 95 % intervals assume a right "
                         "model and understate the uncertainty")


def judged(predictor: Predictor, result: FitResult, twin: Twin | None = None) -> tuple[FitResult, Floor, bool]:
    """``result`` judged against the floor of its own twin (``noise_floor``): (the result, with
    the intervals' warning where it misses above the floor, the floor, whether it explains the
    recording). An interval is the spread of estimates a right model would give; a model that
    misses the recording above its floor carries the miss in its parameters, uncounted.
    ``twin``: the result's ``Twin``, where the caller has made it already."""
    floor = noise_floor(predictor, result.structure, twin=twin)
    explained = floor.explained(result.nrmse_test)
    if not explained:
        result = replace(result, warnings=[*result.warnings, UNEXPLAINED_INTERVALS])
    return result, floor, explained


def noise_floor(predictor: Predictor, structure: Structure | None = None, seed: int = 0,
                twin: Twin | None = None) -> Floor:
    """The floor of the recording behind ``predictor``; with ``structure``, its twin too (module doc),
    drawn from ``twin`` where given (``structure``'s, made by the caller)."""
    windows = predictor.test
    signals = predictor.reported_signals
    noise, quantum = sensors(predictor.m)
    spread = {s: predictor.spread(s, windows) for s in signals}
    measurement = {s: noise[s] / spread[s] for s in signals}
    own, note = {}, ""
    if structure is not None:
        own, note = _twin_floor(twin or Twin(predictor, structure, noise, quantum), signals, seed)
    return Floor(noise, quantum, measurement, own, note, signals, tuple(predictor.signals))


def _twin_floor(twins: Twin, signals: tuple[str, ...], seed: int) -> tuple[dict[str, float], str]:
    """NRMSE per signal of the twins' model predicting its own noisy twin in the same windows,
    the mean square over TWIN_DRAWS draws of the noise."""
    rng = np.random.default_rng(seed)
    squares = {s: 0.0 for s in signals}
    for _ in range(TWIN_DRAWS):
        twin = twins.draw(rng)
        if twin is None:
            return {}, twins.note.replace("the model's", "the final model's")
        windows = twin.test
        (pred,) = twin.predict([twins.structure], windows)
        for s, v in twin.nrmse(pred, windows).items():
            if s in squares:
                squares[s] += v ** 2 / TWIN_DRAWS
    out = {s: float(np.sqrt(v)) for s, v in squares.items()}
    if not all(np.isfinite(v) and v < 1.0 for v in out.values()):
        # A floor at the signal's own spread (no better than its mean) would make any model
        # look explained.
        return {}, "the final model could not predict its own twin (NRMSE 1 or more): no twin"
    return out, ""
