"""Validation helpers shared by every parameter set.

Parameter sets are frozen dataclasses; each field is checked in ``__post_init__`` so a bad
value fails where it is made, with a message naming the value and the allowed range.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any


def check(name: str, value: Any, lo: float | None = None, hi: float | None = None,
          *, lo_open: bool = False, hi_open: bool = False) -> float:
    """Return ``value`` as float if finite and inside the range, else raise ``ValueError``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}={value!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}={value!r} must be finite")
    below = lo is not None and (v <= lo if lo_open else v < lo)
    above = hi is not None and (v >= hi if hi_open else v > hi)
    if below or above:
        left = "(" if lo_open else "["
        right = ")" if hi_open or hi is None else "]"
        lo_s = "-inf" if lo is None else f"{lo:g}"
        hi_s = "inf" if hi is None else f"{hi:g}"
        raise ValueError(f"{name}={v:g} is outside the allowed range {left}{lo_s}, {hi_s}{right}")
    return v


def is_number(text: str) -> bool:
    """Whether ``float(text)`` succeeds."""
    try:
        float(text)
    except (TypeError, ValueError):
        return False
    return True


def fields_dict(obj: Any) -> dict[str, Any]:
    """Shallow field dict of a dataclass instance (tuples kept as tuples)."""
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}


def from_mapping(cls: type, data: dict[str, Any], where: str):
    """Build dataclass ``cls`` from a mapping, rejecting unknown keys with a one-line error."""
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"unknown key {where}.{unknown[0]} (allowed: {', '.join(sorted(known))})")
    return cls(**data)


def fitting_timestep(rate: float, timestep: float) -> float:
    """``timestep`` where the sample rate ``rate`` is the model rate divided by an integer
    (``substeps``), else the largest step below it that divides the sample period: a recording
    at 4 kHz, 800 Hz or 1024 Hz is simulated at that step against a 0.5 ms model, not refused."""
    try:
        substeps(rate, timestep)
        return timestep
    except ValueError:
        period = 1.0 / rate
        return period / math.ceil(period / timestep)


def substeps(rate: float, timestep: float, name: str = "sample_rate") -> int:
    """Model steps per sample: ``rate`` must be the model rate 1/``timestep`` divided by an integer.

    The tolerance admits rates computed from recorded timestamps (1/dt carries rounding), not a
    rate whose samples would drift against the steps.
    """
    sub = round(1.0 / (rate * timestep))
    if sub < 1 or abs(sub * timestep * rate - 1.0) > 1e-6:
        raise ValueError(f"{name}={rate:g} Hz must be the model rate 1/timestep={1 / timestep:g} Hz "
                         "divided by an integer")
    return int(sub)
