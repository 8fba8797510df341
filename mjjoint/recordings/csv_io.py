"""Text tables of samples (.csv, .tsv, .txt, .dat): a header line naming the columns, then one
sample per line.

The separator is the header's: a comma, else a tab, else a semicolon, else runs of spaces.
Lines starting with ``#`` or ``%`` are comments (instrument and MATLAB exports put notes
before the header). Where the separator is not a comma, a decimal comma (``1,25``, as
spreadsheets in many locales write numbers) reads as a decimal point. A time column of ISO 8601
stamps (``2024-05-01 12:00:00.125``, as loggers and pandas write them) is seconds from its first
stamp, to the microsecond.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path
from typing import ClassVar

import numpy as np

from ..params import is_number
from .errors import RecordingError, listing, quote
from .model import MultiRecording, Recording

COMMENTS = ("#", "%")
SEPARATORS = (",", "\t", ";")
_DECIMAL_COMMA = re.compile(r"(?<=\d),(?=\d)")


@dataclass(frozen=True)
class CsvTable:
    """Header and raw text fields of a CSV file; a column is parsed only when it is asked for."""

    file: str
    names: tuple[str, ...]
    rows: tuple[list[str], ...]
    lines: tuple[int, ...]  # file line of each data row, for messages
    kind: ClassVar[str] = "column"
    strict: ClassVar[bool] = True  # every column is a signal, so an unknown one is a mistake

    def column(self, name: str, role: str) -> np.ndarray:
        """Column `name` as float64, used as `role`; names the line of the first bad field."""
        if name not in self.names:
            raise RecordingError(f"{self.file}: column {quote(name)} (for {role}) not found; header has {listing(self.names)}")
        k = self.names.index(name)
        if role == "t" and self.rows and _stamp(self.rows[0][k]) is not None and not is_number(self.rows[0][k]):
            return self._seconds(k, name)
        values = np.empty(len(self.rows))
        for i, row in enumerate(self.rows):
            try:
                values[i] = float(row[k])
            except ValueError:
                raise RecordingError(
                    f"{self.file}: line {self.lines[i]}, column {quote(name)}: {quote(row[k])} is not a number"
                ) from None
        return values

    def _seconds(self, k: int, name: str) -> np.ndarray:
        """A column of ISO 8601 time stamps as seconds from the first, to the microsecond."""
        first = _stamp(self.rows[0][k])
        values = np.empty(len(self.rows))
        for i, row in enumerate(self.rows):
            stamp = _stamp(row[k])
            try:
                values[i] = (stamp - first) / _MICROSECOND * 1e-6
            except TypeError:  # not a stamp, or one with a time zone where the first has none
                raise RecordingError(f"{self.file}: line {self.lines[i]}, column {quote(name)}: {quote(row[k])} is "
                                     f"not a time stamp like the first one, {quote(self.rows[0][k])}") from None
        return values


_MICROSECOND = timedelta(microseconds=1)


def _stamp(field: str) -> datetime | None:
    """An ISO 8601 date and time (``2024-05-01 12:00:00.125``, ``...T12:00:00Z``), or None."""
    try:
        return datetime.fromisoformat(field.strip())
    except ValueError:
        return None


def read_csv_table(path: Path) -> CsvTable:
    """Read and check the structure of a CSV file (header, field counts); opened read-only."""
    where = str(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RecordingError(f"{where}: cannot read ({exc.strerror or exc})") from None
    try:
        text = data.decode("utf-8-sig")  # -sig: spreadsheet exports often start with a BOM
    except UnicodeDecodeError as exc:
        raise RecordingError(f"{where}: not UTF-8 text (invalid byte at offset {exc.start})") from None
    numbered = [(k, line) for k, line in enumerate(text.splitlines(), start=1)
                if line.strip() and not line.lstrip().startswith(COMMENTS)]
    if not numbered:
        raise RecordingError(f"{where}: empty file (no header, no data)")
    sep = _separator(numbered[0][1])
    rows: list[list[str]] = []
    lines: list[int] = []
    if sep is None:
        for k, line in numbered:
            rows.append(line.split())
            lines.append(k)
    else:
        reader = csv.reader((line for _, line in numbered), delimiter=sep)
        try:
            for (k, _), row in zip(numbered, reader):
                rows.append([field.strip() for field in row])
                lines.append(k)
        except csv.Error as exc:
            raise RecordingError(f"{where}: line {numbered[len(rows)][0]}: malformed CSV ({exc})") from None
    if sep != ",":
        rows = [rows[0]] + [[_DECIMAL_COMMA.sub(".", field) for field in row] for row in rows[1:]]
    header, data_rows, data_lines = rows[0], rows[1:], lines[1:]
    _check_header(where, header, lines[0])
    if not data_rows:
        raise RecordingError(f"{where}: header but no data rows")
    for row, line in zip(data_rows, data_lines):
        if len(row) != len(header):
            raise RecordingError(
                f"{where}: line {line} has {len(row)} field(s) but the header has {len(header)} (truncated or ragged row)"
            )
    return CsvTable(where, tuple(header), tuple(data_rows), tuple(data_lines))


def _separator(header: str) -> str | None:
    """The header's separator (module doc); None: runs of whitespace."""
    return next((sep for sep in SEPARATORS if sep in header), None)


def _check_header(where: str, header: list[str], line: int) -> None:
    if all(is_number(name) for name in header):
        raise RecordingError(f"{where}: no header: line {line} is numeric; the first line must name the columns, e.g. t,u,q,theta")
    for k, name in enumerate(header, start=1):
        if not name:
            raise RecordingError(f"{where}: header field {k} is empty")
    duplicated = sorted({name for name in header if header.count(name) > 1})
    if duplicated:
        raise RecordingError(f"{where}: duplicated column name(s) {listing(duplicated)} in the header")


def write_recording(path: str | Path, rec: Recording | MultiRecording) -> None:
    """Write `rec` as CSV: header t,u,q,theta[,tau] (per joint u1,q1,... for several joints).

    Values are written with repr(), the shortest text that reads back to the same float.
    """
    path = Path(path)
    if path.suffix.lower() != ".csv":
        raise RecordingError(f"{path}: recordings are written as .csv")
    signals = rec.signals()
    table = np.column_stack(list(signals.values()))
    with path.open("w", encoding="utf-8", newline="") as f:
        f.write(",".join(signals) + "\n")
        f.writelines(",".join(map(repr, row)) + "\n" for row in table.tolist())
