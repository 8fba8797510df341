"""Parquet tables (pandas, polars, LeRobot-style robot datasets), read with pyarrow.

Each numeric or boolean column is an array by its name (dots are part of a name:
``observation.state``); a column of equal-length lists (a joint vector per sample) is an
N x k array whose signals are picked as ``NAME[:, j]``; a time stamp column is seconds from
its first stamp. Other columns
(strings, ragged lists) are not signals and are left out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .arrays import ArrayTable
from .errors import RecordingError


def read_parquet_table(path: Path) -> ArrayTable:
    """The signal columns of a Parquet file (module doc)."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
        table = pq.read_table(path)
    except Exception as exc:  # corrupt input surfaces as many low-level error types
        raise RecordingError(f"{path}: not a readable Parquet file ({type(exc).__name__}: {exc})") from None
    arrays = {}
    for name in table.column_names:
        column = table.column(name).combine_chunks()
        kind = column.type
        if pa.types.is_timestamp(kind):
            ticks = column.cast(pa.int64()).to_numpy(zero_copy_only=False)
            # From the first stamp, in integers: epoch nanoseconds as float64 keep only ~0.2 us.
            arrays[name] = (ticks - ticks[0]) * _seconds(kind.unit) if len(ticks) else ticks.astype(np.float64)
        elif pa.types.is_integer(kind) or pa.types.is_floating(kind) or pa.types.is_boolean(kind):
            arrays[name] = np.asarray(column.to_numpy(zero_copy_only=False), dtype=np.float64)
        elif (pa.types.is_list(kind) or pa.types.is_fixed_size_list(kind)) and len(column):
            lengths = np.asarray(column.value_lengths().to_numpy(zero_copy_only=False))
            if lengths.min() == lengths.max() > 0 and _numeric(column.type.value_type):
                values = np.asarray(column.flatten().to_numpy(zero_copy_only=False), dtype=np.float64)
                arrays[name] = values.reshape(len(column), -1)
    if not arrays:
        raise RecordingError(f"{path}: no numeric column in the Parquet table (columns: {', '.join(table.column_names)})")
    return ArrayTable(str(path), arrays)


def _numeric(kind) -> bool:
    import pyarrow as pa
    return pa.types.is_integer(kind) or pa.types.is_floating(kind) or pa.types.is_boolean(kind)


def _seconds(unit: str) -> float:
    return {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}[unit]
