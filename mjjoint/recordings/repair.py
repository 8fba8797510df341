"""Rows a logger writes twice or drops, taken out before a recording's checks.

Real logs hold both: a sample written twice (the same time and the same values, e.g. a logger
that polls faster than its source updates) carries nothing new and is dropped whatever the
options. A sample with a non-finite value (a sensor dropout, a field the logger left empty) is
dropped only with ``allow_gaps``: it then leaves a gap that the reader interpolates across, as
a gap in time. Samples with the same time and other values are not touched: which one is
right is not knowable, and the checks refuse them.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


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


def describe(report: Mapping[str, Any]) -> str:
    """One line for the user and the run record: which rows were dropped."""
    parts = []
    if report["repeated_rows"]:
        parts.append(f"{report['repeated_rows']} row(s) repeating the one before (same time and values)")
    if report["dropouts"]:
        parts.append(f"{report['dropouts']} sample(s) with a non-finite value, interpolated across")
    return "dropped " + " and ".join(parts)
