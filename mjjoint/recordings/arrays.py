"""Named arrays from a container file (.mat, .npz), picked by name, struct path and index.

A source name is `NAME`, `NAME[i]` / `NAME[i, :]` (row i of a 2-D array), or `NAME[:, j]`
(column j: MATLAB's usual N x k layout, one signal per column). Indices are 0-based as in
NumPy (MATLAB's `data(:, 4)` is `data[:, 3]`). In .mat files NAME may be a dotted path into
structs, `rec.time_cont` or `log.motor.q`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .errors import RecordingError, listing, quote

FORMS = "NAME, NAME[i] or NAME[i, :] (row i), NAME[:, j] (column j), 0-based; NAME may be a struct path a.b.c"
_INDEXED = re.compile(r"(.+?)\s*\[([^\[\]]*)\]")
_INT = re.compile(r"[+-]?[0-9]+")


@dataclass(frozen=True)
class Pick:
    """A parsed source name: the variable's path and, for a 2-D variable, which row or column."""

    path: str
    axis: int | None = None  # 0: a row, 1: a column
    index: int | None = None
    bare: bool = False  # NAME[i] rather than NAME[i, :]

    @property
    def label(self) -> str:
        return "row" if self.axis == 0 else "column"


def parse_pick(source: str, what: str) -> Pick:
    """`data[:, 3]` -> Pick('data', 1, 3); raises RecordingError naming the allowed forms."""
    m = _INDEXED.fullmatch(source.strip())
    if m is None:
        if "[" in source or "]" in source:
            raise RecordingError(f"{what}: cannot parse it; allowed: {FORMS}")
        return Pick(source.strip())
    parts = [p.strip() for p in m[2].split(",")]
    if len(parts) == 1 and _INT.fullmatch(parts[0]):
        return Pick(m[1], 0, int(parts[0]), bare=True)
    if len(parts) == 2 and _INT.fullmatch(parts[0]) and parts[1] == ":":
        return Pick(m[1], 0, int(parts[0]))
    if len(parts) == 2 and parts[0] == ":" and _INT.fullmatch(parts[1]):
        return Pick(m[1], 1, int(parts[1]))
    raise RecordingError(f"{what}: unsupported index [{m[2]}]; allowed: {FORMS}")


@dataclass(frozen=True)
class ArrayTable:
    """Top-level variables of a .mat or .npz file (MATLAB structs as NumPy record arrays)."""

    file: str
    arrays: Mapping[str, np.ndarray]
    kind: ClassVar[str] = "variable"
    # Containers routinely hold gains and parameters next to the signals: extra names are normal.
    strict: ClassVar[bool] = False
    lines: ClassVar[None] = None

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.arrays)

    def column(self, name: str, role: str) -> np.ndarray:
        """The 1-D float64 signal `name` (see the module's forms) used as `role`."""
        pick = parse_pick(name, f"{self.file}: source {quote(name)} (for {role})")
        what = f"{self.file}: variable {quote(pick.path)} (for {role})"
        return as_signal(self._lookup(pick.path, what), pick, what)

    def _lookup(self, path: str, what: str) -> np.ndarray:
        """The variable `path`, or the field it names inside a (nested) MATLAB struct."""
        if path in self.arrays:
            return np.asarray(self.arrays[path])
        head, *fields = path.split(".")
        if head not in self.arrays or not fields:
            raise RecordingError(f"{what} not found; available variables: {listing(self.names)}")
        x, walked = np.asarray(self.arrays[head]), head
        for f in fields:
            if not x.dtype.names:
                raise RecordingError(f"{what}: {quote(walked)} is not a struct (shape {x.shape}, dtype {x.dtype}), so has no field {quote(f)}")
            if x.size != 1:
                raise RecordingError(f"{what}: {quote(walked)} is a struct array of shape {x.shape}; only a single struct can be entered")
            if f not in x.dtype.names:
                raise RecordingError(f"{what}: struct {quote(walked)} has no field {quote(f)}; fields: {listing(x.dtype.names)}")
            x, walked = np.asarray(x.flat[0][f]), f"{walked}.{f}"
        return x


def as_signal(x: np.ndarray, pick: Pick, what: str) -> np.ndarray:
    """The 1-D float64 signal `pick` selects from the array `x` (a variable, a dataset)."""
    if x.dtype.names:
        raise RecordingError(f"{what} is a struct with fields {listing(x.dtype.names)}; pick one with {pick.path}.FIELD")
    if x.dtype.kind not in "iuf":
        raise RecordingError(f"{what} is not a real numeric array (dtype {x.dtype})")
    if pick.index is not None:
        x = _take(x, pick, what)
    elif x.ndim == 2 and 1 in x.shape:
        x = x.ravel()  # MATLAB stores every vector as N×1 or 1×N
    if x.ndim != 1:
        hint = f"; pick a column with {pick.path}[:, j] or a row with {pick.path}[i, :]" if x.ndim == 2 else ""
        raise RecordingError(f"{what} has shape {x.shape}, expected a vector{hint}")
    return x.astype(np.float64)


def _take(x: np.ndarray, pick: Pick, what: str) -> np.ndarray:
    if x.ndim != 2:
        raise RecordingError(f"{what}: a {pick.label} index needs a 2-D array, got shape {x.shape}")
    n = x.shape[pick.axis]
    if not 0 <= pick.index < n:
        raise RecordingError(
            f"{what}: {pick.label} {pick.index} is out of range for shape {x.shape}; "
            f"allowed {pick.label}s 0..{n - 1} (0-based, no negative indices)"
        )
    if pick.bare and x.shape[1] < x.shape[0]:
        # An N x k matrix (N samples): NAME[i] would take k values of sample i, not a signal.
        raise RecordingError(
            f"{what}: {pick.path}[{pick.index}] is row {pick.index} ({x.shape[1]} values) of shape {x.shape}, "
            f"whose columns are the signals; write {pick.path}[:, {pick.index}] for column {pick.index}"
        )
    return x[pick.index] if pick.axis == 0 else x[:, pick.index]
