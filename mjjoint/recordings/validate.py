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
    # An angle past its limit is accepted when it turns like a shaft in rad (see _not_turning).
    "q": (1e6, ""),
    "theta": (1e3, ""),
}
# A large angle in counts is whole numbers; in degrees it moves 57x too far per sample.
ANGLES = frozenset({"q", "theta"})
MAX_ANGLE_STEP = 1.0  # [rad per sample]; under pi with margin: a larger step aliases anyway
MAX_SPEED = 1e4  # [rad/s], about 95 000 rpm: beyond any motor
COUNTS_HINT = "looks like encoder counts: set --scales {name}=FACTOR with FACTOR = 2*pi/(counts per revolution)"
DEGREES_HINT = "looks like degrees or counts: set --scales {name}=deg or {name}=FACTOR"


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


def check_signals(signals: Mapping[str, np.ndarray], ctx: Context, allow_gaps: bool = False) -> None:
    """Raise RecordingError for the first problem found; signals must include 't'.

    allow_gaps: accept steps longer than MAX_GAP median periods (the reader interpolates across them).
    """
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
                f"column {ctx.column(name)} has {float(x[i])!r} at {ctx.sample(i)} ({bad.size} non-finite value(s)); "
                "pass allow_gaps=True (--allow-gaps) to drop such samples and interpolate across them"
            )
    check_time(t, ctx, allow_gaps)
    for name, x in signals.items():
        _check_magnitude(name, x, t, ctx)


def check_time(t: np.ndarray, ctx: Context, allow_gaps: bool) -> None:
    """Time strictly increasing, in seconds by its median period, without gaps unless allowed."""
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
        raise ctx.error(period_problem(dt, float(t[-1] - t[0])))
    gaps = np.flatnonzero(d > MAX_GAP * dt)
    if gaps.size and not allow_gaps:
        i = int(gaps[0]) + 1
        raise ctx.error(
            f"gap in time before {ctx.sample(i)}: step {d[i - 1]:.6g} s after t={float(t[i - 1])!r} "
            f"is {d[i - 1] / dt:.1f}x the median period {dt:.6g} s ({gaps.size} gap(s)); "
            "pass allow_gaps=True (--allow-gaps) to interpolate linearly across gaps"
        )


def period_problem(dt: float, span: float, scales: bool = True) -> str | None:
    """Why a median period ``dt`` outside [DT_MIN, DT_MAX] is refused, naming the likely unit
    and, with ``scales``, the option that reads it (else: write t in seconds); None within."""
    if DT_MIN <= dt <= DT_MAX:
        return None
    plain = (f"median sample period {dt:.3g} s ({1 / dt:.3g} Hz over {span:.6g} s) is outside "
             f"[{DT_MIN:g}, {DT_MAX:g}] s")
    if dt > DT_MAX:
        for unit, factor in TIME_UNITS:
            if DT_MIN <= dt * factor <= DT_MAX:
                return (f"t looks like {unit}: {plain}; read as {unit} it is {1 / (dt * factor):.6g} Hz "
                        f"over {span * factor:.6g} s " + (f"(set --scales t={factor:g})" if scales else
                                                          "(write t in seconds)"))
    return f"{plain}; is t in seconds?" + (" (e.g. --scales t=1e-3 for milliseconds)" if scales else "")


def _check_magnitude(name: str, x: np.ndarray, t: np.ndarray, ctx: Context) -> None:
    kind = split_joint(name)[0]
    if kind not in LIMITS:
        return
    limit, hint = LIMITS[kind]
    i = int(np.argmax(np.abs(x)))
    if abs(x[i]) <= limit:
        return
    reaches = f"column {ctx.column(name)} reaches {float(x[i]):.6g} at {ctx.sample(i)} (|{name}| > {limit:g})"
    if kind in ANGLES:
        why = _not_turning(x, t, ctx)
        if why is None:
            return  # a shaft that turned many revolutions, in rad
        reaches, hint = f"{reaches} and {why[0]}", why[1]
    raise ctx.error(f"{reaches}; " + hint.format(name=name))


def _not_turning(x: np.ndarray, t: np.ndarray, ctx: Context) -> tuple[str, str] | None:
    """(what gives it away, hint) when a large angle is not a shaft turning in rad, else None."""
    if np.all(x == np.round(x)):
        return "every value is a whole number", COUNTS_HINT
    step = np.abs(np.diff(x))
    j = int(np.argmax(step))
    if step[j] > MAX_ANGLE_STEP:
        return f"jumps by {step[j]:.4g} at {ctx.sample(j + 1)} (over {MAX_ANGLE_STEP:g} rad per sample)", DEGREES_HINT
    speed = step / np.diff(t)
    j = int(np.argmax(speed))
    if speed[j] > MAX_SPEED:
        return f"moves at {speed[j]:.4g} per s at {ctx.sample(j + 1)} (over {MAX_SPEED:g} rad/s)", DEGREES_HINT
    return None
