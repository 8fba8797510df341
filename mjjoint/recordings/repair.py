"""What loggers do to a recording, undone before its checks: rows written twice or dropped,
angles wrapped to one turn.

Real logs hold both: a sample written twice (the same time and the same values, e.g. a logger
that polls faster than its source updates) carries nothing new and is dropped whatever the
options. A sample with a non-finite value (a sensor dropout, a field the logger left empty) is
dropped only with ``allow_gaps``: it then leaves a gap that the reader interpolates across, as
a gap in time. Samples with the same time and other values are not touched: which one is
right is not knowable, and the checks refuse them.

A single-turn encoder logs its angle wrapped to one revolution ([0, 2 pi), [-pi, pi), or 0-360
degrees once scaled): read as it is, the motor seems to jump a turn back within a sample and
the deflection q/N - theta is nonsense. An angle whose typical (median) step is under
``MAX_ANGLE_STEP`` and whose every step over half a turn lies within ``MAX_ANGLE_STEP`` of one
turn, up or down, is unwrapped (``unwrap_angles``); a real shaft cannot move half a turn in
one sample anyway (the samples would alias it).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .columns import split_joint
from .validate import ANGLES, MAX_ANGLE_STEP

TURN = 2.0 * np.pi


def repair(signals: Mapping[str, np.ndarray], allow_gaps: bool,
           lines: Sequence[int] | None = None) -> tuple[dict[str, np.ndarray], Sequence[int] | None, dict[str, Any] | None]:
    """(signals, their file lines, what was dropped or None) with the rows of the module doc
    taken out; the signals include 't'."""
    n = len(signals["t"])
    if any(len(x) != n for x in signals.values()):  # the checks name the column
        return dict(signals), lines, None
    keep = np.ones(n, bool)
    repeated = np.ones(max(n - 1, 0), bool)
    for x in signals.values():
        repeated &= x[1:] == x[:-1]  # a row with a NaN is never a repeat: NaN != NaN
    keep[1:] &= ~repeated
    dropouts = 0
    if allow_gaps:
        finite = np.logical_and.reduce([np.isfinite(x) for x in signals.values()])
        dropouts = int(np.count_nonzero(~finite))
        keep &= finite
    if keep.all():
        return dict(signals), lines, None
    report = {"repeated_rows": int(np.count_nonzero(repeated)), "dropouts": dropouts}
    kept_lines = None if lines is None else [line for line, k in zip(lines, keep) if k]
    return {name: x[keep] for name, x in signals.items()}, kept_lines, report


def unwrap_angles(signals: Mapping[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict[str, int]]:
    """(signals with the wrapped angles unwrapped, how many turns were added back per angle)."""
    out, turns = dict(signals), {}
    for name, x in signals.items():
        if split_joint(name)[0] not in ANGLES or len(x) < 2 or not np.isfinite(x).all():
            continue  # a non-finite sample is the checks' to report, before any arithmetic on it
        d = np.diff(x)
        big = np.flatnonzero(np.abs(d) > 0.5 * TURN)
        if big.size == 0 or np.median(np.abs(d)) > MAX_ANGLE_STEP:
            continue  # nothing wrapped, or every step large: an angle in other units (degrees), for the checks
        k = np.round(d[big] / TURN)
        if np.any(np.abs(k) != 1) or np.any(np.abs(d[big] - k * TURN) > MAX_ANGLE_STEP):
            continue  # not a wrap: the checks judge the angle as it is
        jumps = np.zeros(len(x))
        jumps[big + 1] = k * TURN
        out[name] = x - np.cumsum(jumps)
        turns[name] = int(big.size)
    return out, turns


def describe_unwrapped(turns: Mapping[str, int]) -> str:
    """One line for the user and the run record: which angles were unwrapped."""
    return "unwrapped " + ", ".join(f"{name} ({n} jump(s) of a whole turn: an angle read within one revolution)"
                                    for name, n in turns.items())


def describe(report: Mapping[str, Any]) -> str:
    """One line for the user and the run record: which rows were dropped."""
    parts = []
    if report["repeated_rows"]:
        parts.append(f"{report['repeated_rows']} row(s) repeating the one before (same time and values)")
    if report["dropouts"]:
        parts.append(f"{report['dropouts']} sample(s) with a non-finite value, interpolated across")
    return "dropped " + " and ".join(parts)
