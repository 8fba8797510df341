"""Which recordings a fleet holds: a folder, a glob, or a manifest (CSV or TOML) with options.

A manifest lists one recording a row (CSV, a ``recording`` column) or a ``[[recording]]``
table each (TOML, a ``path`` key), with optional per-recording options named as the
command-line ones (``gear_ratio``, ``columns``, ``scales``, ...) that replace the command
line's for that recording, and ``name``, the report folder (default: the file's stem).
Relative paths in a manifest are relative to the manifest's folder, so it travels with the data.
"""
from __future__ import annotations

import csv
import glob
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ..modelfile import brief, one_line

RECORDING_SUFFIXES = (".csv", ".npz", ".mat")
GLOB_CHARS = frozenset("*?[")
# Per-recording options a manifest may set: what differs between robots and their logs.
OPTIONS = ("gear_ratio", "columns", "scales", "k_m", "allow_gaps", "joint", "model", "base", "plant")
PATH_OPTIONS = ("model",)
NAME_KEYS = {".csv": "recording", ".toml": "path"}


@dataclass(frozen=True)
class Entry:
    """One recording of the fleet: its report folder name, its file, options that replace the CLI's."""

    name: str
    path: Path
    options: dict = field(default_factory=dict)

    def __post_init__(self):
        if not self.name or self.name in (".", "..") or set(self.name) & set("/\\\0"):
            raise ValueError(f"recording name {self.name!r} cannot be a folder name; give a plain name")


def _is_manifest_csv(path: Path) -> bool:
    with open(path, newline="", encoding="utf-8", errors="replace") as f:
        header = next(csv.reader(f), [])
    return NAME_KEYS[".csv"] in (h.strip() for h in header)


def is_fleet(spec: str | Path) -> bool:
    """Whether the recording argument names several recordings (folder, glob, manifest)."""
    path = Path(spec)
    if path.is_dir():
        return True
    if not path.exists():
        return bool(GLOB_CHARS & set(str(spec)))
    return path.suffix.lower() == ".toml" or (path.suffix.lower() == ".csv" and _is_manifest_csv(path))


def resolve(spec: str | Path) -> list[Entry]:
    """The fleet's recordings in a stable order; a one-line ``ValueError`` for an empty or ambiguous one."""
    path = Path(spec)
    if path.is_dir():
        entries = _files(sorted(path.iterdir()))
    elif not path.exists():
        entries = _files(sorted(Path(p) for p in glob.glob(str(spec), recursive=True)))
    else:
        entries = _manifest(path)
    if not entries:
        raise ValueError(f"{spec}: holds no recording (.csv, .npz, .mat)")
    seen: dict[str, Path] = {}
    for e in entries:
        if e.name in seen:
            raise ValueError(f"{seen[e.name]} and {e.path} would both report into {e.name}/; "
                             "list them in a manifest with a 'name' each")
        seen[e.name] = e.path
    return entries


def _files(paths: list[Path]) -> list[Entry]:
    return [Entry(p.stem, p) for p in paths if p.suffix.lower() in RECORDING_SUFFIXES and p.is_file()]


def _manifest(path: Path) -> list[Entry]:
    suffix = path.suffix.lower()
    if suffix == ".toml":
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except ValueError as exc:  # a decode error, or an integer too long to convert
            raise ValueError(f"{path}: not valid TOML ({one_line(exc)})") from None
        extra = set(data) - {"recording"}
        if extra or not isinstance(data.get("recording", []), list):
            raise ValueError(f"{path}: a manifest holds only [[recording]] tables (found {sorted(extra) or 'recording'})")
        rows = [(f"{path} [[recording]] {i}", r) for i, r in enumerate(data.get("recording", []), 1)]
    else:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f, skipinitialspace=True)
            header = [h.strip() for h in reader.fieldnames or ()]
            if "" in header or len(set(header)) < len(header):
                raise ValueError(f"{path}: the header names each column once, none empty (found {header})")
            # Empty cells leave the command line's value: a column may be set for some rows only.
            rows = [(f"{path} line {reader.line_num}", _csv_row(path, reader.line_num, row)) for row in reader]
    return [_entry(path.parent, where, row, NAME_KEYS[suffix]) for where, row in rows]


def _csv_row(path: Path, line: int, row: dict) -> dict:
    """A manifest line's filled cells; more cells than the header names is an error, not ignored."""
    if None in row:
        raise ValueError(f"{path} line {line}: more cells than the header names")
    return {k.strip(): v.strip() for k, v in row.items() if v is not None and v.strip()}


def _entry(base: Path, where: str, row, key: str) -> Entry:
    if not isinstance(row, dict):
        raise ValueError(f"{where}: a recording's entry is a table of keys, not {brief(row)}")
    allowed = (key, "name", *OPTIONS)
    unknown = [k for k in row if k not in allowed]
    if unknown:
        raise ValueError(f"{where}: unknown key {unknown[0]!r} (allowed: {', '.join(allowed)})")
    if key not in row:
        raise ValueError(f"{where}: no {key!r} (the recording's file)")
    if not isinstance(row[key], str) or not isinstance(row.get("name", ""), str):
        raise ValueError(f"{where}: {key!r} and 'name' are text (a file, a folder name)")
    file = base / str(row[key])
    options = {k: _text(v) for k, v in row.items() if k in OPTIONS}
    for k in PATH_OPTIONS:
        if k in options:
            options[k] = str(base / options[k])
    return Entry(str(row.get("name", file.stem)), file, options)


def _text(value) -> str:
    """A manifest value as the command line would give it (a list is a comma list)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return ",".join(_text(v) for v in value)
    return str(value)
