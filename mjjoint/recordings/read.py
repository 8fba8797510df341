"""`read_recording`: load a text table, .npz, .mat, HDF5, Parquet or JSON file or a robot log, map and scale its columns, check them."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from .columns import ALLOWED, OPTIONAL, SIGNALS, check_column_map, check_scales, expand_scales, resolve_columns, split_joint
from .csv_io import read_csv_table
from .derived import parse as parse_expression, read_columns
from .errors import RecordingError, listing
from .h5_io import read_h5_table
from .json_io import read_json_table
from .log_io import CLOCKS, LogTable, is_log_folder, read_log_table
from .mat_io import read_mat_table
from .model import MultiRecording, Recording
from .npz_io import read_npz_table
from .parquet_io import read_parquet_table
from .repair import describe as describe_repair, describe_unwrapped, repair, unwrap_angles
from .resample import describe as describe_resampling, to_uniform_grid
from .validate import Context, check_signals


class _Table(Protocol):
    kind: str  # "column" or "variable", for messages
    strict: bool  # whether a name the mapping does not use is an error
    lines: Sequence[int] | None
    names: tuple[str, ...]

    def column(self, name: str, role: str) -> np.ndarray: ...


_LOADERS: dict[str, Callable[[Path], _Table]] = {
    ".csv": read_csv_table,
    ".tsv": read_csv_table,
    ".txt": read_csv_table,
    ".dat": read_csv_table,
    ".npz": read_npz_table,
    ".mat": read_mat_table,
    ".h5": read_h5_table,
    ".hdf5": read_h5_table,
    ".mcap": read_log_table,
    ".parquet": read_parquet_table,
    ".json": read_json_table,
    ".jsonl": read_json_table,
}


def _positive(name: str, value: float | None) -> float | None:
    if value is None:
        return None
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise RecordingError(f"{name} must be a number, got {value!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise RecordingError(f"{name} must be finite and positive, got {value!r}")
    return value


def read_recording(
    path: str | Path,
    columns: Mapping[str, str] | None = None,
    scales: Mapping[str, float] | None = None,
    gear_ratio: float | None = None,
    k_m: float | None = None,
    *,
    allow_extra: bool = False,
    allow_gaps: bool = False,
    timestep: float | None = None,
) -> Recording | MultiRecording:
    """Read a recording and return it in canonical names and SI units.

    Jittered or non-uniform timestamps are resampled onto a uniform grid by linear
    interpolation (resample.to_uniform_grid); meta['resampled'] says how, and is None for a
    recording left as recorded. Rows repeating the one before are dropped, and with
    ``allow_gaps`` samples with a non-finite value too (repair.repair); meta['repaired'] says
    how many, and is None where none was. Angles read within one revolution are unwrapped
    (repair.unwrap_angles; meta['unwrapped']: the jumps per angle, or None).

    Args:
        path: a .csv, .npz or .mat (v5) file.
        columns: canonical name -> name in the file (see parse_column_map); unmapped signals
            are looked up under their canonical name.
        scales: canonical name -> multiplier to SI (see parse_scales).
        gear_ratio: stored with the recording (motor angle q is before the gear).
        k_m: torque constant [N m/A]; when given, the u column holds a current and u = k_m i.
        allow_extra: accept CSV columns that no signal uses.
        allow_gaps: interpolate across steps longer than 5 median periods, and across samples
            with a non-finite value, instead of refusing.
        timestep: [s] make the resampled period a multiple of it.

    Returns:
        A ``Recording`` (t, u, q, theta[, tau], each of shape (n,)), or a ``MultiRecording``
        for several joints (columns u1, q1, theta1, ...).

    Raises:
        RecordingError: (a ``ValueError``) a file that cannot be read or signals that fail the
            checks, in one line naming the column.
    """
    signals, meta = read_signals(path, columns, scales, k_m, allow_extra=allow_extra, allow_gaps=allow_gaps,
                                 timestep=timestep)
    return _build(signals, _positive("gear_ratio", gear_ratio), meta)


def read_signals(
    path: str | Path,
    columns: Mapping[str, str] | None = None,
    scales: Mapping[str, float] | None = None,
    k_m: float | None = None,
    *,
    allow_extra: bool = False,
    allow_gaps: bool = False,
    timestep: float | None = None,
    layout: Sequence[str] = SIGNALS,
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """(signals by canonical name, meta) of a file, checked and on a uniform grid, as
    `read_recording` reads them; `layout`: a single joint's signals, all of them required
    unless they are the recording's own (SIGNALS, tau optional), e.g. ('t', 'q', 'tau') for a
    friction log."""
    where, path = str(path), Path(path)
    columns = check_column_map(columns or {})
    scales = check_scales(scales or {})
    k_m = _positive("k_m", k_m)
    timestep = _positive("timestep", timestep)
    if not path.exists():
        raise RecordingError(f"{where}: no such file")
    if is_log_folder(path):
        loader = read_log_table
    elif not path.is_file():
        raise RecordingError(f"{where}: not a regular file (nor a ROS 2 bag folder with metadata.yaml)")
    else:
        loader = _LOADERS.get(path.suffix.lower())
    if loader is None:
        raise RecordingError(f"{where}: unsupported file type {path.suffix!r}; expected {', '.join(_LOADERS)} "
                             "or a ROS 2 bag folder")
    if path.is_file() and path.stat().st_size == 0:
        raise RecordingError(f"{where}: empty file")

    table = loader(path)
    if isinstance(table, LogTable):
        columns = {"t": CLOCKS[0], **columns}  # a log's time is a choice of clock, not a topic
    layout = tuple(layout)
    sources = resolve_columns(table.names, columns, where, table.kind, layout,
                              OPTIONAL if layout == SIGNALS else ())
    factors = expand_scales(scales, sources, where)
    merged = None
    if isinstance(table, LogTable):
        derived = [name for name, source in sources.items() if parse_expression(source) is not None]
        if derived:
            raise RecordingError(f"{where}: {derived[0]}={sources[derived[0]]!r}: a robot log's signals are "
                                 "topic fields; expressions are read from files only")
        raw, merged = table.merged(sources, timestep, allow_gaps)
        used = set(sources.values())
    else:
        raw, used = read_columns(sources, table.column, where)
    signals = {}
    for name, x in raw.items():
        x = x * factors.get(name, 1.0)
        signals[name] = x * k_m if k_m is not None and split_joint(name)[0] == "u" else x
    # After the lookups above, so that a mistyped mapping is reported as such, not as an unused column.
    # Unknown names are refused (a mistyped signal name would go unnoticed), unless --columns
    # names the columns to use: a log's other columns are then left out, with a note.
    extra = [name for name in table.names if name not in used] if table.strict else []
    if extra and not (allow_extra or columns):
        raise RecordingError(
            f"{where}: unknown column(s) {listing(extra)}; allowed: {ALLOWED}; name the columns to use with "
            "--columns (the others are then left out) or pass allow_extra=True to ignore them"
        )
    signals, lines, repaired = repair(signals, allow_gaps, table.lines)
    signals, turns = unwrap_angles(signals)
    check_signals(signals, Context(where, sources, lines), allow_gaps)
    signals, resampled = to_uniform_grid(signals, timestep)

    meta = {"source": where, "format": "rosbag2" if path.is_dir() else path.suffix.lower()[1:], "columns": sources,
            "scales": factors, "k_m": k_m, "repaired": repaired,
            "unwrapped": turns or None, "resampled": merged or resampled,
            "left_out": None if allow_extra or not extra else extra}
    return signals, meta


def reading_notes(meta: Mapping[str, Any]) -> list[str]:
    """One line for each thing reading did to the recording as recorded: rows dropped
    (``meta['repaired']``), angles unwrapped (``meta['unwrapped']``), resampling
    (``meta['resampled']``), columns no signal was mapped to (``meta['left_out']``)."""
    return [describe(meta[key]) for key, describe in (("repaired", describe_repair), ("unwrapped", describe_unwrapped),
                                                     ("resampled", describe_resampling), ("left_out", _describe_left_out))
            if meta.get(key) is not None]


def _describe_left_out(names) -> str:
    return f"columns no signal is mapped to, left out: {listing(names)}"


def _build(signals: dict[str, np.ndarray], gear_ratio: float | None, meta: dict[str, Any]) -> Recording | MultiRecording:
    if "u" in signals:
        return Recording(**signals, gear_ratio=gear_ratio, meta=meta)
    joints = sorted({j for name in signals if (j := split_joint(name)[1]) is not None})
    return MultiRecording(
        tuple(
            Recording(
                t=signals["t"],
                u=signals[f"u{j}"],
                q=signals[f"q{j}"],
                theta=signals[f"theta{j}"],
                tau=signals.get(f"tau{j}"),
                gear_ratio=gear_ratio,
                meta={**meta, "joint": j},
            )
            for j in joints
        ),
        meta=meta,
    )
