"""The noise floor of a recording: how closely the right model could predict it.

A verdict is a claim about the final model's held-out misfit, so it is judged against what a
correct model would still miss on this very recording, per signal, in the NRMSE the fits
report (rms error over the signal's spread within the held-out windows):

- **measurement noise**: the white part of each recorded signal (its robust spread about a
  smoothing, ``windows.noise_std``), and at least its quantisation (the common step of its
  values, step / sqrt(12));
- **the windowing**: a simulated twin of the recording, made by the final model itself under
  the measured input without restarts, with that noise and quantisation added (the rounding
  is part of the noise measured: only the rest is drawn before it), predicted by the same
  model in the same windows, over TWIN_DRAWS draws of the noise. Its misfit is what window starts reconstructed from
  noisy samples and hidden states (pre-sliding, lag, hysteresis) cost a model that is right,
  as a share of the twin's own spread. A twin that wanders into another regime than the
  recording's (an open-loop run of a closed-loop recording that drifts off; a model far from
  the truth) gives none (``TWIN_SPREAD``), and so does a twin its model predicts no better
  than the signal's mean (NRMSE 1 or more): the floor is then the noise's alone, and the
  verdict the stricter for it. Stacked recordings stay apart in the twin as in the recording;
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
from ..identify.windows import Measured, Predictor, noise_std
from ..recordings import Recording

RESOLUTION = 0.01      # NRMSE no model comparison resolves below (module doc)
EXPLAINED_RATIO = 1.5  # held-out NRMSE up to this multiple of the floor: within the noise
# The twin's windowing floor counts up to this multiple of the recording's own (module doc).
WINDOWING_TRUST = 2.0
# A quantisation step is accepted when this share of the nonzero sample-to-sample changes are
# whole multiples of the smallest one (to QUANTUM_TOL of it): a float signal's changes are not.
QUANTUM_SHARE = 0.95
# A twin whose signals spread more than this factor further or less far than the recording's is
# in another regime (module doc): it gives no floor.
TWIN_SPREAD = 2.0
QUANTUM_TOL = 1e-2
# Noise draws a twin's floor averages: with a few held-out windows, one draw's floor moves by
# half its value from draw to draw.
TWIN_DRAWS = 4
FEW_STEPS = 20  # changes up to this many steps refine the step's estimate


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


def quantisation_step(x: np.ndarray) -> float:
    """The step a quantised signal's values move by (0 when they move by arbitrary amounts)."""
    d = np.abs(np.diff(np.asarray(x, float)))
    d = d[d > 0]
    if d.size < 10:
        return 0.0
    step = float(np.min(d))
    # Refined over the changes of a few steps: values printed to ~10 significant digits carry the
    # smallest change only to ~1e-4 of a step, which a change of 1000 steps multiplies past the
    # tolerance (a motor encoder at speed).
    small = d[d < (FEW_STEPS + 0.5) * step]
    k = np.round(small / step)
    step = float(np.dot(small, k) / np.dot(k, k))
    k = d / step
    on_grid = np.abs(k - np.round(k)) <= QUANTUM_TOL
    return step if np.mean(on_grid) >= QUANTUM_SHARE else 0.0


def sensor_noise(x: np.ndarray, rate: float, per_segment=None) -> tuple[float, float]:
    """(noise std, quantisation step) of a recorded signal: the std at least step / sqrt(12);
    ``per_segment``: each stacked recording smoothed on its own (``windows.noise_std``)."""
    step = quantisation_step(x)
    return max(noise_std(x, rate, per_segment), step / np.sqrt(12.0)), step


UNEXPLAINED_INTERVALS = ("the model misses the recording above its noise floor: its 95 % intervals assume a right "
                         "model and understate the uncertainty")


def judged(predictor: Predictor, result: FitResult) -> tuple[FitResult, Floor, bool]:
    """``result`` judged against the floor of its own twin (``noise_floor``): (the result, with
    the intervals' warning where it misses above the floor, the floor, whether it explains the
    recording). An interval is the spread of estimates a right model would give; a model that
    misses the recording above its floor carries the miss in its parameters, uncounted."""
    floor = noise_floor(predictor, result.structure)
    explained = floor.explained(result.nrmse_test)
    if not explained:
        result = replace(result, warnings=[*result.warnings, UNEXPLAINED_INTERVALS])
    return result, floor, explained


def measured_signals(m: Measured) -> dict[str, np.ndarray]:
    return {k: v for k, v in (("q", m.q), ("theta", m.theta), ("delta", m.measured_delta), ("tau", m.tau))
            if v is not None}


def noise_floor(predictor: Predictor, structure: Structure | None = None, seed: int = 0) -> Floor:
    """The floor of the recording behind ``predictor``; with ``structure``, its twin too (module doc)."""
    m = predictor.m
    windows = predictor.test
    signals = tuple(s for s in ("q", "theta", "delta", "tau") if predictor.meas.get(s) is not None)
    noise, quantum = {}, {}
    for s, x in measured_signals(m).items():
        noise[s], quantum[s] = sensor_noise(x, m.rate, m.per_segment)
    if "delta" in noise:  # derived from q and theta: their noises add, whatever the fit of its own
        noise["delta"] = float(np.hypot(noise["q"] / m.gear_ratio, noise["theta"]))
        quantum["delta"] = 0.0
    spread = {s: predictor.spread(s, windows) for s in signals}
    measurement = {s: noise[s] / spread[s] for s in signals}
    twin, note = {}, ""
    if structure is not None:
        twin, note = _twin_floor(predictor, structure, noise, quantum, spread, seed)
    return Floor(noise, quantum, measurement, twin, note, signals, tuple(predictor.signals))


def _twin_floor(predictor: Predictor, structure: Structure, noise: dict, quantum: dict, spread: dict,
                seed: int) -> tuple[dict[str, float], str]:
    """NRMSE per signal of ``structure`` predicting its own noisy twin in the same windows, the
    mean square over TWIN_DRAWS draws of the noise."""
    run = predictor.free_run(structure)
    m = predictor.m
    if not all(np.all(np.isfinite(run[s])) for s in ("q", "theta", "tau") if getattr(m, s) is not None):
        return {}, "the final model's free run of the recording diverged: no twin"
    rng = np.random.default_rng(seed)
    # One encoder's theta is q/N: its twin's too, drawn with q's noise.
    present = [s for s in ("q", "theta", "tau") if getattr(m, s) is not None and (s != "theta" or m.link_encoder)]
    analog = {s: _analog_noise(run[s], noise[s], quantum[s], m) for s in present}

    def recorded(s: str) -> np.ndarray:
        x = run[s] + rng.normal(0.0, analog[s], len(run[s]))
        return np.round(x / quantum[s]) * quantum[s] if quantum[s] > 0 else x
    squares = {s: 0.0 for s in spread}
    for _ in range(TWIN_DRAWS):
        drawn = {s: recorded(s) for s in present}
        # A direct drive's recording has no theta: a placeholder, which from_recording ignores.
        theta = drawn.get("theta", drawn["q"] / m.gear_ratio if m.theta is not None else np.zeros_like(m.t))
        tau = drawn.get("tau")
        # Stacked recordings stay apart: velocities taken across a join would start a window
        # there with the jump between two recordings as its speed.
        twin_m = Measured.stack([
            Measured.from_recording(Recording(t=m.t[a:b], u=m.u[a:b], q=drawn["q"][a:b], theta=theta[a:b],
                                              tau=None if tau is None else tau[a:b]),
                                    m.gear_ratio, output=m.theta is not None)
            for a, b in m.segments])
        twin = predictor.on(twin_m)
        windows = twin.test
        for s in spread:
            ratio = twin.spread(s, windows) / spread[s]
            if not 1 / TWIN_SPREAD <= ratio <= TWIN_SPREAD:
                # An open-loop run of a closed-loop recording, or a model far off, wanders
                # elsewhere: its windowing costs say nothing about this recording's.
                return {}, (f"the final model's free run is not like the recording ({s} spreads {ratio:.2g}x as "
                            "far): no twin")
        (pred,) = twin.predict([structure], windows)
        for s, v in twin.nrmse(pred, windows).items():
            if s in squares:
                squares[s] += v ** 2 / TWIN_DRAWS
    out = {s: float(np.sqrt(v)) for s, v in squares.items()}
    if not all(np.isfinite(v) and v < 1.0 for v in out.values()):
        # A floor at the signal's own spread (no better than its mean) would make any model
        # look explained.
        return {}, "the final model could not predict its own twin (NRMSE 1 or more): no twin"
    return out, ""


def _analog_noise(x: np.ndarray, noise: float, quantum: float, m: Measured) -> float:
    """The std of the noise a twin draws before rounding to ``quantum``: the recording's noise
    less what the same estimator (``noise_std``) reads off the noise-free signal ``x`` rounded
    alone, so that a sensor that only rounds gets a twin that only rounds."""
    if quantum <= 0:
        return noise
    rounded = max(noise_std(np.round(x / quantum) * quantum, m.rate, m.per_segment), quantum / np.sqrt(12.0))
    return float(np.sqrt(max(noise ** 2 - rounded ** 2, 0.0)))
