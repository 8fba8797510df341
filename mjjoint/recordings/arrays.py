"""Named arrays from a container file (.mat, .npz), picked by name or by row: `name[i]`."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .errors import RecordingError, listing, quote

_ROW = re.compile(r"(.+)\[([0-9]+)\]")


@dataclass(frozen=True)
class ArrayTable:
    """Top-level variables of a .mat or .npz file."""

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
        """The 1-D float64 signal `name` (or row i of a 2-D variable for `name[i]`) used as `role`."""
        m = _ROW.fullmatch(name)
        var, row = (m[1], int(m[2])) if m else (name, None)
        what = f"{self.file}: variable {quote(var)} (for {role})"
        if var not in self.arrays:
            raise RecordingError(f"{what} not found; available variables: {listing(self.names)}")
        x = self.arrays[var]
        if x.dtype.kind not in "iuf":
            raise RecordingError(f"{what} is not a real numeric array (dtype {x.dtype})")
        if row is not None:
            if x.ndim != 2 or row >= x.shape[0]:
                raise RecordingError(f"{what}: cannot take row {row} of an array of shape {x.shape}")
            x = x[row]
        elif x.ndim == 2 and 1 in x.shape:
            x = x.ravel()  # MATLAB stores every vector as N×1 or 1×N
        if x.ndim != 1:
            hint = f"; pick a row with {var}[i]" if x.ndim == 2 else ""
            raise RecordingError(f"{what} has shape {x.shape}, expected a vector{hint}")
        return x.astype(np.float64)
