"""Reading .mat files: v5 (scipy.io.loadmat) and v7.3, which is HDF5 (h5_io)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import scipy.io

from .arrays import ArrayTable
from .errors import RecordingError
from .h5_io import H5Table, read_h5_table
from .mat_guard import MAT_V73, check_mat_v5, mat_version


def read_mat_table(path: Path) -> ArrayTable | H5Table:
    """All top-level variables of a .mat file; the file is only read."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read ({exc.strerror or exc})") from None
    try:
        if mat_version(data) == MAT_V73:
            return read_h5_table(path, matlab=True)
        check_mat_v5(data)
    except ValueError as exc:
        raise RecordingError(f"{path}: not a readable MATLAB v5 file: {exc}") from None
    try:
        variables = scipy.io.loadmat(io.BytesIO(data))
    except Exception as exc:  # corrupt input surfaces as many low-level error types
        raise RecordingError(f"{path}: not a readable MATLAB v5 file ({type(exc).__name__}: {exc})") from None
    # Unreadable variables come back as message strings; asarray lets the column check name them.
    return ArrayTable(str(path), {k: np.asarray(v) for k, v in variables.items() if not k.startswith("__")})
