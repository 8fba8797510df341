"""Reading MATLAB v5 .mat files (scipy.io.loadmat), top-level variables only."""

from __future__ import annotations

from pathlib import Path

import scipy.io

from .arrays import ArrayTable
from .errors import RecordingError


def read_mat_table(path: Path) -> ArrayTable:
    """All top-level variables of a .mat file; the file is opened read-only."""
    try:
        with path.open("rb") as f:
            data = scipy.io.loadmat(f)
    except NotImplementedError:  # loadmat's answer to v7.3, which is HDF5
        raise RecordingError(f"{path}: MATLAB v7.3 files are not supported; re-save with save(..., '-v7')") from None
    except Exception as exc:  # corrupt input surfaces as many low-level error types
        raise RecordingError(f"{path}: not a readable MATLAB v5 file ({type(exc).__name__}: {exc})") from None
    return ArrayTable(str(path), {k: v for k, v in data.items() if not k.startswith("__")})
