"""Motor-torque excitations u(t) [N m] for open-loop experiments on the joint.

Each excitation is a frozen, validated dataclass; ``sample(rate, duration)`` returns u at the
sample instants t_k = k / rate, the value the Simulator holds over [t_k, t_k + 1/rate).
Default amplitudes suit the shipped arm: its motor friction (TwoSEP defaults: 0.08 N m
Coulomb, 0.12 N m break-away) keeps torques below ~0.12 N m in pre-sliding, while the 160:1
gear makes a constant 0.13 N m outweigh the ~4.6 N m of gravity at the link and swing the
arm over the top. So the step lifts the link by ~35-45 deg, the chirp and the multisine slide
the motor through the friction (link swing below ~5 deg, deflection below 2 mrad), and the
impulse is the chapter's 5 A x k_m for 1.5 ms (Sec. 4).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .params import check
from .recordings.csv_io import read_csv_table
from .recordings.validate import period_problem


def sample_times(rate: float, duration: float) -> np.ndarray:
    """Sample instants k / rate covering ``duration`` seconds (at least one sample)."""
    check("rate", rate, 0.0, lo_open=True)
    check("duration", duration, 0.0, lo_open=True)
    n = int(round(rate * duration))
    if n < 1:
        raise ValueError(f"duration={duration:g} s holds no sample at rate={rate:g} Hz")
    return np.arange(n) / rate


def _held_fraction(n: int, rate: float, start: float, stop: float) -> np.ndarray:
    """Share of each hold interval [k, k + 1) / rate, k < n, inside [start, stop).

    Scaling a pulse's level by this share keeps its area and switching instants exact even
    when they fall between samples (1.5 ms at 1 kHz). Counted in samples, with instants
    within rounding of the grid snapped onto it, so an on-grid switch gives full levels.
    """
    k = np.arange(n, dtype=float)
    a, b = _on_grid(start * rate), _on_grid(stop * rate)
    return np.clip(np.minimum(k + 1, b) - np.maximum(k, a), 0.0, 1.0)


def _on_grid(s: float) -> float:
    return float(round(s)) if math.isfinite(s) and abs(s - round(s)) < 1e-9 * max(1.0, abs(s)) else s


def _below_nyquist(name: str, f: float, rate: float) -> None:
    if f >= rate / 2:
        raise ValueError(f"{name}={f:g} Hz is outside the allowed range (0, {rate / 2:g}) Hz "
                         f"below the Nyquist frequency at rate={rate:g} Hz")


def _starts_within(t0: float, duration: float) -> None:
    """An input that would start after the run is a mistake, not a run at rest."""
    if not t0 < duration:
        raise ValueError(f"t0={t0:g} s is not before the run's end ({duration:g} s): the input would be 0 throughout")


@dataclass(frozen=True)
class Step:
    """u = amplitude from t0 on, 0 before."""

    amplitude: float = 0.1   # [N m]: lifts the link ~35-45 deg, held by gravity and friction
    t0: float = 0.5          # [s]: half a second of rest first

    def __post_init__(self) -> None:
        check("amplitude", self.amplitude)
        check("t0", self.t0, 0.0)

    def sample(self, rate: float, duration: float) -> np.ndarray:
        n = len(sample_times(rate, duration))
        _starts_within(self.t0, duration)
        return self.amplitude * _held_fraction(n, rate, self.t0, math.inf)


@dataclass(frozen=True)
class Impulse:
    """A rectangular pulse of ``amplitude`` over [t0, t0 + width): area = amplitude x width."""

    amplitude: float = 1.25  # [N m]: 5 A x k_m = 0.25 N m/A, the chapter's FRF impulse (Sec. 4)
    t0: float = 0.1          # [s]
    width: float = 1.5e-3    # [s]: 1.5 ms as in Sec. 4

    def __post_init__(self) -> None:
        check("amplitude", self.amplitude)
        check("t0", self.t0, 0.0)
        check("width", self.width, 0.0, lo_open=True)

    def sample(self, rate: float, duration: float) -> np.ndarray:
        n = len(sample_times(rate, duration))
        _starts_within(self.t0, duration)
        return self.amplitude * _held_fraction(n, rate, self.t0, self.t0 + self.width)


SWEEPS = ("linear", "log")


@dataclass(frozen=True)
class Chirp:
    """A sine sweeping from f_start to f_end over the whole sampled duration.

    The default is the chapter's 30 -> 1 Hz down-chirp (Sec. 4); "log" sweeps the frequency
    geometrically (equal time per octave) instead of linearly.
    """

    amplitude: float = 0.15  # [N m]: above break-away, |tau| ~ 20 N m, link swings a few deg
    f_start: float = 30.0    # [Hz]
    f_end: float = 1.0       # [Hz]
    sweep: str = "linear"

    def __post_init__(self) -> None:
        check("amplitude", self.amplitude)
        check("f_start", self.f_start, 0.0, lo_open=True)
        check("f_end", self.f_end, 0.0, lo_open=True)
        if self.sweep not in SWEEPS:
            raise ValueError(f"sweep={self.sweep!r} is not a known sweep (allowed: {', '.join(SWEEPS)})")

    def frequency(self, t: np.ndarray, duration: float) -> np.ndarray:
        """Instantaneous frequency [Hz] at times t of a sweep lasting ``duration``."""
        s = np.asarray(t) / duration
        if self.sweep == "log":
            return self.f_start * (self.f_end / self.f_start) ** s
        return self.f_start + (self.f_end - self.f_start) * s

    def sample(self, rate: float, duration: float) -> np.ndarray:
        t = sample_times(rate, duration)
        for name in ("f_start", "f_end"):
            _below_nyquist(name, getattr(self, name), rate)
        T = len(t) / rate
        f0, f1 = self.f_start, self.f_end
        if self.sweep == "log" and f0 != f1:
            # integral of f0 r^(t/T) dt with r = f1/f0
            cycles = f0 * T * ((f1 / f0) ** (t / T) - 1.0) / math.log(f1 / f0)
        else:
            cycles = f0 * t + 0.5 * (f1 - f0) * t ** 2 / T
        return self.amplitude * np.sin(2 * np.pi * cycles)


@dataclass(frozen=True)
class Multisine:
    """Sum of n random-phase sines between f_min and f_max, scaled to a peak of ``amplitude``.

    The lines sit on the record's frequency grid (whole periods in the sampled duration), so
    the spectrum is exactly the n lines, with no leakage out of the band.
    """

    amplitude: float = 0.25  # [N m] peak (RMS ~1/3 of it): slides the motor, |tau| ~ 13 N m
    f_min: float = 1.0       # [Hz]
    f_max: float = 30.0      # [Hz]: the chirp's band
    n: int = 16              # number of lines
    seed: int = 0            # random phases

    def __post_init__(self) -> None:
        check("amplitude", self.amplitude)
        check("f_min", self.f_min, 0.0, lo_open=True)
        check("f_max", self.f_max, self.f_min)
        for name in ("n", "seed"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ValueError(f"{name}={value!r} must be an integer")
        check("n", self.n, 1)
        check("seed", self.seed, 0)

    def frequencies(self, duration: float) -> np.ndarray:
        """The n line frequencies [Hz] for a record of ``duration`` seconds."""
        lo, hi = math.ceil(self.f_min * duration - 1e-9), math.floor(self.f_max * duration + 1e-9)
        if hi - lo + 1 < self.n:
            raise ValueError(f"n={self.n} is outside the allowed range [1, {max(hi - lo + 1, 0)}]: only that many "
                             f"whole-period lines fit in [{self.f_min:g}, {self.f_max:g}] Hz over {duration:g} s")
        # Spacing >= 1 bin, so rounding keeps the n lines distinct.
        return np.round(np.linspace(lo, hi, self.n)) / duration

    def sample(self, rate: float, duration: float) -> np.ndarray:
        t = sample_times(rate, duration)
        _below_nyquist("f_max", self.f_max, rate)
        f = self.frequencies(len(t) / rate)
        phase = np.random.default_rng(self.seed).uniform(0.0, 2 * np.pi, self.n)
        u = np.sin(2 * np.pi * f[None, :] * t[:, None] + phase[None, :]).sum(axis=1)
        return self.amplitude * u / np.abs(u).max()


@dataclass(frozen=True)
class FromFile:
    """A torque column of a CSV file (header naming t and the column), zero-order held.

    Time is taken relative to the file's first row; the file must cover every requested
    sample instant. Read and checked when made, so a bad file fails here.
    """

    path: str | Path
    column: str = "u"
    time_column: str = "t"

    def __post_init__(self) -> None:
        path = Path(self.path)
        object.__setattr__(self, "path", path)
        if not path.is_file():
            raise ValueError(f"{path}: no such file")
        table = read_csv_table(path)
        t = table.column(self.time_column, "time")
        u = table.column(self.column, "excitation")
        bad = np.flatnonzero(~np.isfinite(t) | ~np.isfinite(u))
        if bad.size:
            raise ValueError(f"{path}: line {table.lines[bad[0]]} holds a NaN or inf")
        steps = np.diff(t)
        if np.any(steps <= 0):
            k = int(np.flatnonzero(steps <= 0)[0]) + 1
            raise ValueError(f"{path}: line {table.lines[k]}: time {float(t[k])!r} does not increase")
        problem = period_problem(float(np.median(steps)), float(t[-1] - t[0]), scales=False) if steps.size else None
        if problem is not None:  # t in milliseconds would run the input a thousand times slower
            raise ValueError(f"{path}: {problem}")
        # Derived data, not fields: equality and repr stay those of the file reference.
        object.__setattr__(self, "t", t - t[0])
        object.__setattr__(self, "u", u)

    @property
    def duration(self) -> float:
        """Span of the file including the hold of its last row (one median sample period)."""
        return float(self.t[-1] + (np.median(np.diff(self.t)) if len(self.t) > 1 else 0.0))

    def sample(self, rate: float, duration: float) -> np.ndarray:
        ts = sample_times(rate, duration)
        if ts[-1] >= self.duration - 1e-9 * max(1.0, self.duration):
            raise ValueError(f"{self.path}: covers {self.duration:g} s but duration={duration:g} s was requested")
        return self.u[np.searchsorted(self.t, ts * (1 + 1e-12) + 1e-12, side="right") - 1]


# name -> class, as the CLI's --excitation spells them
EXCITATIONS: dict[str, type] = {
    "step": Step, "impulse": Impulse, "chirp": Chirp, "multisine": Multisine, "file": FromFile,
}


def excitation_fields(cls: type) -> dict[str, object]:
    """Settable fields of an excitation class and their defaults (``dataclasses.MISSING`` if required)."""
    return {f.name: f.default for f in dataclasses.fields(cls)}
