"""Data checks on a recording's signals once they are in canonical names and SI units."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from .columns import split_joint
from .errors import RecordingError

MIN_SAMPLES = 10
MAX_GAP = 5.0  # a step this many times the median period is a gap, not jitter
# [s]; outside this, t is almost surely not in seconds. Below 10 Hz no joint dynamics are
# sampled (resonances lie at tens of Hz), while a 1 kHz recording with t in milliseconds has
# a median period of exactly 1 "s".
DT_MIN, DT_MAX = 1e-7, 0.1
TIME_UNITS = (("milliseconds", 1e-3), ("microseconds", 1e-6), ("nanoseconds", 1e-9))

# Largest plausible magnitude per signal kind, and what a larger value usually means.
LIMITS: dict[str, tuple[float, str]] = {
    "u": (1e6, "wrong units? set --scales {name}=FACTOR, or --k-m if it is a current"),
    "tau": (1e6, "wrong units? set --scales {name}=FACTOR"),
    "q": (1e6, "likely encoder counts or degrees: set --scales {name}=deg or {name}=FACTOR"),
    "theta": (1e3, "likely degrees or counts: try --scales {name}=deg"),
}


@dataclass(frozen=True)
class Context:
    """Where the signals came from, so that messages point into the file."""

    file: str
    sources: Mapping[str, str] = field(default_factory=dict)  # canonical -> name in the file
    lines: Sequence[int] | None = None  # file line of each sample (CSV only)

    def column(self, name: str) -> str:
        source = self.sources.get(name, name)
        return repr(name) if source == name else f"{name!r} (from {source!r})"

    def sample(self, i: int) -> str:
        return f"sample {i}" + (f" (line {self.lines[i]})" if self.lines is not None else "")

    def error(self, message: str) -> RecordingError:
        return RecordingError(f"{self.file}: {message}")


def check_signals(signals: Mapping[str, np.ndarray], ctx: Context) -> None:
    """Raise RecordingError for the first problem found; signals must include 't'."""
    t = signals["t"]
    for name, x in signals.items():
        if len(x) != len(t):
            raise ctx.error(f"column {ctx.column(name)} has {len(x)} samples but 't' has {len(t)}")
    if len(t) < MIN_SAMPLES:
        raise ctx.error(f"only {len(t)} samples; need at least {MIN_SAMPLES}")
    for name, x in signals.items():
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            i = int(bad[0])
            raise ctx.error(
                f"column {ctx.column(name)} has {float(x[i])!r} at {ctx.sample(i)} ({bad.size} non-finite value(s))"
            )
    _check_time(t, ctx)
    for name, x in signals.items():
        _check_magnitude(name, x, ctx)


def _check_time(t: np.ndarray, ctx: Context) -> None:
    # Extreme but finite times overflow to inf here; the period checks below then report them.
    with np.errstate(over="ignore"):
        d = np.diff(t)
    back = np.flatnonzero(d <= 0)
    if back.size:
        i = int(back[0]) + 1
        how = "duplicated" if d[i - 1] == 0 else "decreasing"
        raise ctx.error(
            f"time is not strictly increasing ({how}) at {ctx.sample(i)}: t={float(t[i])!r} after t={float(t[i - 1])!r}"
        )
    dt = float(np.median(d))
    if not DT_MIN <= dt <= DT_MAX:
        raise ctx.error(_time_unit_message(dt, float(t[-1] - t[0])))
    gaps = np.flatnonzero(d > MAX_GAP * dt)
    if gaps.size:
        i = int(gaps[0]) + 1
        raise ctx.error(
            f"gap in time before {ctx.sample(i)}: step {d[i - 1]:.6g} s after t={float(t[i - 1])!r} "
            f"is {d[i - 1] / dt:.1f}x the median period {dt:.6g} s ({gaps.size} gap(s))"
        )


def _time_unit_message(dt: float, span: float) -> str:
    """Why a median period ``dt`` outside [DT_MIN, DT_MAX] is refused, naming the likely unit."""
    plain = (f"median sample period {dt:.3g} s ({1 / dt:.3g} Hz over {span:.6g} s) is outside "
             f"[{DT_MIN:g}, {DT_MAX:g}] s")
    if dt > DT_MAX:
        for unit, factor in TIME_UNITS:
            if DT_MIN <= dt * factor <= DT_MAX:
                return (f"t looks like {unit}: {plain}; read as {unit} it is {1 / (dt * factor):.6g} Hz "
                        f"over {span * factor:.6g} s (set --scales t={factor:g})")
    return f"{plain}; is t in seconds? (e.g. --scales t=1e-3 for milliseconds)"


def _check_magnitude(name: str, x: np.ndarray, ctx: Context) -> None:
    kind = split_joint(name)[0]
    if kind not in LIMITS:
        return
    limit, hint = LIMITS[kind]
    i = int(np.argmax(np.abs(x)))
    if abs(x[i]) > limit:
        raise ctx.error(
            f"column {ctx.column(name)} reaches {float(x[i]):.6g} at {ctx.sample(i)} (|{name}| > {limit:g}); "
            + hint.format(name=name)
        )
