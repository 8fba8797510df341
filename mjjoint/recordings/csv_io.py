"""CSV recordings: a header line naming the columns, then one sample per line, comma-separated."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from ..params import is_number
from .errors import RecordingError, listing, quote
from .model import MultiRecording, Recording



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
        values = np.empty(len(self.rows))
        for i, row in enumerate(self.rows):
            try:
                values[i] = float(row[k])
            except ValueError:
                raise RecordingError(
                    f"{self.file}: line {self.lines[i]}, column {quote(name)}: {quote(row[k])} is not a number"
                ) from None
        return values


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
    reader = csv.reader(io.StringIO(text, newline=""))
    rows: list[list[str]] = []
    lines: list[int] = []
    try:
        for row in reader:
            if len(row) <= 1 and not "".join(row).strip():
                continue  # blank line
            rows.append([field.strip() for field in row])
            lines.append(reader.line_num)
    except csv.Error as exc:
        raise RecordingError(f"{where}: line {reader.line_num}: malformed CSV ({exc})") from None
    if not rows:
        raise RecordingError(f"{where}: empty file (no header, no data)")
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


def _check_header(where: str, header: list[str], line: int) -> None:
    if all(is_number(name) for name in header):
        raise RecordingError(f"{where}: no header: line {line} is numeric; the first line must name the columns, e.g. t,u,q,theta")
    if len(header) == 1 and any(sep in header[0] for sep in ";\t"):
        raise RecordingError(f"{where}: header {quote(header[0])} is a single column; the file must be comma-separated")
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
