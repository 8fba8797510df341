"""Outputs that appear complete or not at all, and JSON that is byte-reproducible.

An output folder (``fit``/``diagnose --out``) is written into ``DIR.partial-<pid>`` beside
``DIR`` (same filesystem, so the final rename is atomic) and renamed to ``DIR`` only when every
file is there. Output files (``simulate --csv/--plot/--rrd``) are written as
``NAME.partial-<pid>.EXT`` beside each final name and renamed once all of them are written. An
interrupt or error removes the partial files and folders; a hard kill leaves ones whose names
say they are partial. A complete folder always holds ``run.json``, written last: that marks it
as ours, so a later run may replace it, while a folder of someone else's files is never deleted.

Where outputs may go (``DESTINATION_RULE``, the same for every command): missing folders are
created only inside the working directory; elsewhere the output's folder must already exist.
A typo such as ``/nonexistent/dir/x.csv`` is then an error instead of a new folder tree at the
filesystem root.
"""
from __future__ import annotations

import json
import math
import os
import shutil
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from .. import interrupts

MARKER = "run.json"
DESTINATION_RULE = ("missing folders are created only inside the working directory; "
                    "elsewhere the output's folder must exist")


def check_destination(path: str | Path, option: str) -> None:
    """Raise a one-line error now, before any work, if ``path`` could not be created later.

    Nothing is created yet (a bad input found later must leave no trace): the nearest existing
    ancestor, where missing folders would be made, is checked instead.
    """
    target = Path(os.path.abspath(path))
    base = target.parent
    while not base.exists():
        base = base.parent
    if not base.is_dir():
        raise ValueError(f"{option} {path}: {base} is a file, so {path} cannot be created")
    if base != target.parent and not target.is_relative_to(Path.cwd()):
        raise ValueError(f"{option} {path}: folder {target.parent} does not exist ({DESTINATION_RULE})")
    if not os.access(base, os.W_OK | os.X_OK):
        raise PermissionError(13, "Permission denied", str(base))


def check_folder(path: Path, marker: str = MARKER, what: str = "an mjjoint output") -> None:
    """``--out`` may become or replace ``path``: absent, empty, or holding ``marker`` (ours)."""
    if path.exists() and not path.is_dir():
        raise ValueError(f"{path}: exists and is not a folder; choose another --out")
    if path.is_dir() and any(path.iterdir()) and not (path / marker).is_file():
        raise ValueError(f"{path}: folder exists and is not {what} (no {marker}); "
                         "choose another --out or empty it")
    check_destination(path, "--out")


def partial_name(path: Path) -> Path:
    """Where ``path`` is written before it is complete: beside it, same suffix (the writers go by it)."""
    return path.with_name(f"{path.stem}.partial-{os.getpid()}{path.suffix}")


@contextmanager
def staged_files(paths: Iterable[Path]) -> Iterator[dict[Path, Path]]:
    """Yield final -> partial path for each output file; on success the partials replace the finals.

    On any exception (KeyboardInterrupt included) every partial file is removed and no final
    name is touched, so a file under its final name is always a complete one.
    """
    partial = {Path(p): partial_name(Path(p)) for p in paths}
    start = interrupts.count()
    try:
        for final, tmp in partial.items():
            final.parent.mkdir(parents=True, exist_ok=True)
            tmp.unlink(missing_ok=True)  # leftover of an earlier run with our pid
        yield partial
        missing = [str(f) for f, tmp in partial.items() if not tmp.is_file()]
        if missing:
            raise RuntimeError(f"output not written: {', '.join(missing)}")  # a bug in the command
        interrupts.raise_if_interrupted(start)  # a Ctrl-C Python could not raise where it came
        for final, tmp in partial.items():
            os.replace(tmp, final)
    except BaseException:
        for tmp in partial.values():
            tmp.unlink(missing_ok=True)
        raise


def jsonable(obj: Any) -> Any:
    """Plain JSON types: numpy scalars and arrays converted, tuples as lists, non-finite as null."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return jsonable(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None  # strict JSON has no NaN/inf; null reads as "undefined" everywhere
    return obj


def write_json(path: Path, data: Any) -> Path:
    """``data`` as indented strict JSON with a final newline (same data -> same bytes)."""
    text = json.dumps(jsonable(data), indent=2, allow_nan=False)
    path.write_text(text + "\n", encoding="utf-8")
    return path


class OutputDir:
    """The ``--out`` folder of a command: checked up front, written all at once at the end."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if self.path.name in ("", ".", ".."):  # it is renamed into place: it needs a name of its own
            raise ValueError(f"--out {path}: give a folder name, e.g. {Path(path) / 'results'}")
        self.partial = self.path.with_name(f"{self.path.name}.partial-{os.getpid()}")

    def check(self) -> None:
        """Fail now, before any compute is spent, if the result could not be put in place."""
        check_folder(self.path)

    @contextmanager
    def staged(self) -> Iterator[Path]:
        """Yield the partial folder to write into; on success it becomes ``self.path``."""
        self.check()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        shutil.rmtree(self.partial, ignore_errors=True)  # leftover of an earlier run with our pid
        self.partial.mkdir()
        start = interrupts.count()
        try:
            yield self.partial
            interrupts.raise_if_interrupted(start)
            if not (self.partial / MARKER).is_file():
                raise RuntimeError(f"output written without {MARKER}")  # a bug in the command
            self._replace()
        except BaseException:  # KeyboardInterrupt included: nothing half-written may stay
            shutil.rmtree(self.partial, ignore_errors=True)
            raise

    def _replace(self) -> None:
        old = None
        if self.path.exists():
            old = self.path.with_name(f"{self.path.name}.old-{os.getpid()}")
            os.replace(self.path, old)
        try:
            os.replace(self.partial, self.path)
        except BaseException:
            if old is not None:
                os.replace(old, self.path)  # put the previous complete result back
            raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
