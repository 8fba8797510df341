"""Noisy twins of a recording: what a model would have recorded itself.

A twin is the model's run under the measured input without restarts (``Predictor.free_run``:
through the model's own sensor effects, as its window predictions are), read through the
recording's own sensors: the white noise and the quantisation of each signal,
both measured on the recording (``sensor_noise``). Predicted in the recording's windows, a
twin shows what a model that is right still misses or moves: the noise floor of a verdict
(``diagnosis.floor``) and the bias of a fit's estimates (``fit.twin_bias``), both from window
starts reconstructed out of noisy, quantised samples and from hidden states.
"""
from __future__ import annotations

import numpy as np

from ..recordings import Recording
from .structure import Structure
from .windows import Measured, Predictor, noise_std

# A quantisation step is accepted when this share of the nonzero sample-to-sample changes are
# whole multiples of the smallest one (to QUANTUM_TOL of it): a float signal's changes are not.
QUANTUM_SHARE = 0.95
QUANTUM_TOL = 1e-2
FEW_STEPS = 20  # changes up to this many steps refine the step's estimate
# A twin whose signals spread more than this factor further or less far than the recording's is
# in another regime (an open-loop run of a closed-loop recording that drifts off; a model far
# from the truth): it says nothing about the recording.
TWIN_SPREAD = 2.0


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


def measured_signals(m: Measured) -> dict[str, np.ndarray]:
    return {k: v for k, v in (("q", m.q), ("theta", m.theta), ("delta", m.measured_delta), ("tau", m.tau))
            if v is not None}


def sensors(m: Measured) -> tuple[dict[str, float], dict[str, float]]:
    """(noise std, quantisation step) of each recorded signal (``sensor_noise``)."""
    noise, quantum = {}, {}
    for s, x in measured_signals(m).items():
        noise[s], quantum[s] = sensor_noise(x, m.rate, m.per_segment)
    if "delta" in noise:  # derived from q and theta: their noises add, whatever the fit of its own
        noise["delta"] = float(np.hypot(noise["q"] / m.gear_ratio, noise["theta"]))
        quantum["delta"] = 0.0
    return noise, quantum


def analog_noise(x: np.ndarray, noise: float, quantum: float, m: Measured) -> float:
    """The std of the noise a twin draws before rounding to ``quantum``: the recording's noise
    less what the same estimator (``noise_std``) reads off the noise-free signal ``x`` rounded
    alone, so that a sensor that only rounds gets a twin that only rounds."""
    if quantum <= 0:
        return noise
    rounded = max(noise_std(np.round(x / quantum) * quantum, m.rate, m.per_segment), quantum / np.sqrt(12.0))
    return float(np.sqrt(max(noise ** 2 - rounded ** 2, 0.0)))


class Twin:
    """Noisy twins of the recording behind ``predictor`` made by ``structure`` (module doc):
    one free run, any number of noise draws. ``note`` says why there is none ("" where there is)."""

    def __init__(self, predictor: Predictor, structure: Structure, noise: dict | None = None,
                 quantum: dict | None = None):
        self.predictor, self.structure = predictor, structure
        m = predictor.m
        if noise is None or quantum is None:
            noise, quantum = sensors(m)
        self.quantum = quantum
        self.run = predictor.free_run(structure)
        self.note = ""
        if not all(np.all(np.isfinite(self.run[s])) for s in ("q", "theta", "tau") if getattr(m, s) is not None):
            self.note = "the model's free run of the recording diverged: no twin"
            return
        # One encoder's theta is q/N: its twin's too, drawn with q's noise.
        self.present = [s for s in ("q", "theta", "tau")
                        if getattr(m, s) is not None and (s != "theta" or m.link_encoder)]
        self.analog = {s: analog_noise(self.run[s], noise[s], quantum[s], m) for s in self.present}

    def draw(self, rng: np.random.Generator, fit_signals=None) -> Predictor | None:
        """A predictor of the recording's windows on one noisy twin, scoring ``fit_signals``
        (default every signal it holds); None where the twin spreads unlike the recording
        (TWIN_SPREAD; ``note`` says which signal)."""
        if self.note:
            return None
        m, p = self.predictor.m, self.predictor
        drawn = {s: self._recorded(s, rng) for s in self.present}
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
        twin = p.on(twin_m, fit_signals)
        windows = p.test
        for s in p.reported_signals:
            ratio = twin.spread(s, windows) / p.spread(s, windows)
            if not 1 / TWIN_SPREAD <= ratio <= TWIN_SPREAD:
                self.note = f"the model's free run is not like the recording ({s} spreads {ratio:.2g}x as far): no twin"
                return None
        return twin

    def _recorded(self, s: str, rng: np.random.Generator) -> np.ndarray:
        x = self.run[s] + rng.normal(0.0, self.analog[s], len(self.run[s]))
        q = self.quantum[s]
        return np.round(x / q) * q if q > 0 else x
