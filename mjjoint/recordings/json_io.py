"""JSON recordings: samples as a list of records, as arrays by name, or both nested in an object.

Forms read (names in ``--columns`` are dotted paths, ``[:, j]`` picks from a vector per sample):
- a list of records, ``[{"t": 0.0, "q": 1.2, ...}, ...]`` (also one record per line, ``.jsonl``):
  each key is an array (a nested object's keys dotted: ``motor.q``);
- an object of arrays, ``{"t": [...], "q": [...]}``;
- an object holding a list of records next to scalars (a robot's or a servo's log:
  ``{"kp": 400, "entries": [{"timestamp": 0.0, "position": 0.1}, ...]}``): the records'
  arrays as ``entries.timestamp``, ``entries.position``.
Numbers and booleans are values; a key a record lacks, or null, is NaN (``--allow-gaps``
interpolates it); strings are left out. A number outside the records (a servo's ``kp``) is a
scalar: not a signal, but a constant an expression in ``--columns`` may use (``recordings.derived``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .arrays import ArrayTable
from .errors import RecordingError


def read_json_table(path: Path) -> ArrayTable:
    """The signal arrays of a JSON or JSON Lines file (module doc)."""
    try:
        text = path.read_text(encoding="utf-8-sig")
        data = _lines(text) if path.suffix.lower() == ".jsonl" else json.loads(text)
    except RecursionError:
        raise RecordingError(f"{path}: not a readable JSON file (nested deeper than a recording is)") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise RecordingError(f"{path}: not a readable JSON file ({type(exc).__name__}: {exc})") from None
    arrays: dict[str, np.ndarray] = {}
    _collect(data, "", arrays)
    if not any(a.shape[0] > 1 for a in arrays.values()):
        raise RecordingError(f"{path}: no list of samples found (expected a list of records or arrays of numbers)")
    return ArrayTable(str(path), arrays)


def _collect(node, path: str, arrays: dict[str, np.ndarray]) -> None:
    """The arrays under ``node``, named by their dotted ``path`` from the top."""
    if isinstance(node, dict):
        for key, value in node.items():
            _collect(value, _join(path, key), arrays)
    elif isinstance(node, list) and node and all(isinstance(r, dict) for r in node):
        rows = [_flat(r) for r in node]
        for key in dict.fromkeys(k for r in rows for k in r):
            column = _numbers([r.get(key) for r in rows])
            if column is not None:
                arrays[_join(path, key)] = column
    elif isinstance(node, list) and path:
        column = _numbers(node)
        if column is not None:
            arrays[path] = column
    elif isinstance(node, (bool, int, float)) and path and math.isfinite(value := _float(node)):
        arrays[path] = np.array([value])


def _lines(text: str) -> list:
    """The records of a JSON Lines text; an error names the file's line, not the record's."""
    out = []
    for k, line in enumerate(text.splitlines(), start=1):
        if line.strip():
            try:
                out.append(json.loads(line))
            except json.JSONDecodeError as exc:
                raise ValueError(f"line {k}: {exc.msg} at column {exc.colno}") from None
    return out


def _float(v: bool | int | float) -> float:
    """``float(v)``; an integer beyond every float is infinite (the checks refuse it by name)."""
    try:
        return float(v)
    except OverflowError:
        return math.inf if v > 0 else -math.inf


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _flat(record: dict, path: str = "") -> dict:
    """A record's values by dotted key, nested objects opened."""
    out = {}
    for key, value in record.items():
        if isinstance(value, dict):
            out.update(_flat(value, _join(path, key)))
        else:
            out[_join(path, key)] = value
    return out


def _number(v) -> float | None:
    if v is None:
        return math.nan
    if isinstance(v, (bool, int, float)):
        return _float(v)
    return None


def _numbers(values: list) -> np.ndarray | None:
    """A vector of numbers (None: NaN), or an N x k array of equal-length number lists; None
    where the values are not numeric."""
    if values and all(isinstance(v, list) for v in values):
        rows = [[_number(x) for x in v] for v in values]
        if len({len(r) for r in rows}) == 1 and rows[0] and all(x is not None for r in rows for x in r):
            return np.array(rows, dtype=np.float64)
        return None
    out = [_number(v) for v in values]
    if any(x is None for x in out) or all(math.isnan(x) for x in out):
        return None
    return np.array(out, dtype=np.float64)
