"""Reading NumPy .npz archives, arrays by name."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .arrays import ArrayTable
from .errors import RecordingError


def read_npz_table(path: Path) -> ArrayTable:
    """All arrays of a .npz archive; opened read-only, pickled objects refused."""
    try:
        with path.open("rb") as f:
            archive = np.load(f, allow_pickle=False)
            if not isinstance(archive, np.lib.npyio.NpzFile):
                raise ValueError("holds a single array, not an archive of named arrays")
            with archive:
                arrays = {name: archive[name] for name in archive.files}
    except Exception as exc:  # corrupt input surfaces as many low-level error types
        raise RecordingError(f"{path}: not a readable .npz archive ({type(exc).__name__}: {exc})") from None
    return ArrayTable(str(path), arrays)
