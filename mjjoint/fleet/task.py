"""One recording of a fleet as a unit of work: its report folder, and its rows of fleet.csv.

A task is plain data (the recording's ``diagnose`` arguments with absolute paths, its report
folder, its input hash), so it pickles to a pool process or to a Dask worker on another
machine; the worker reads the recording from that path (a shared filesystem) and writes the
report there, atomically as a single ``diagnose`` does. The rows are read back from the
report's files, so a fresh report and one kept from an earlier run give the same rows.

Finished means: the report folder is complete (``run.json`` is written last) and its run was
given the same input hash, a digest of the recording's and model file's bytes, the options
that shape the result and the mjjoint version.
"""
from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from ..report.output import MARKER
from ..report.summary import SIGNAL_ORDER

# Not part of the result: where things are and how the work is spread.
NOT_HASHED = frozenset({"recording", "model", "out", "workers", "scheduler", "force", "input_hash"})
HASHED_FILES = ("recording", "model")
FIELDS = ("recording", "joint", "status", "verdict", "missing",
          *(f"nrmse_before_{s}" for s in SIGNAL_ORDER), *(f"nrmse_after_{s}" for s in SIGNAL_ORDER),
          "explained", "seconds", "reused", "error", "report")
# One diagnosis at a time per process: a Dask worker with several threads would otherwise run
# two side by side, registering models concurrently in the plugin's process-wide registry.
_ONE_AT_A_TIME = threading.Lock()


@dataclass(frozen=True)
class Task:
    name: str
    arguments: dict  # the ``diagnose`` namespace for this recording, without out and input_hash
    out: Path        # the recording's report folder, DIR/<name>
    input_hash: str

    @property
    def recording(self) -> str:
        return str(self.arguments["recording"])


def _file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def input_hash(arguments: dict) -> str:
    """Digest of what decides a recording's report; a missing file leaves the task to fail alone."""
    from .. import __version__

    files = {}
    for key in HASHED_FILES:
        paths = arguments.get(key)
        # A task's recording is one path; run.json's arguments list the command line's recordings.
        for i, path in enumerate(paths if isinstance(paths, list) else [] if paths is None else [paths]):
            try:
                files[f"{key}{i or ''}"] = _file_digest(Path(path))
            except OSError as exc:
                files[f"{key}{i or ''}"] = f"unreadable: {exc.strerror}"
    options = {k: v for k, v in arguments.items() if k not in NOT_HASHED}
    text = json.dumps({"version": __version__, "files": files, "options": options}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def finished(task: Task) -> bool:
    """Whether the task's complete report from a run with the same input hash is in place."""
    try:
        run = json.loads((task.out / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return run.get("arguments", {}).get("input_hash") == task.input_hash and (task.out / "diagnosis.json").is_file()


def run_task(task: Task) -> list[dict]:
    """Diagnose the task's recording into its report folder; its rows, or one failed row."""
    from ..cli.errors import describe

    with _ONE_AT_A_TIME:
        start = time.perf_counter()
        notes = io.StringIO()
        try:
            with contextlib.redirect_stderr(notes):
                _diagnose(task)
        except Exception as exc:  # any failure stays this recording's: the fleet goes on
            kind = "" if isinstance(exc, (ValueError, OSError)) else f"{type(exc).__name__}: "
            return [failed_row(task, kind + describe(exc), time.perf_counter() - start)]
        finally:
            for line in notes.getvalue().splitlines():
                print(f"{task.name}: {line}", file=sys.stderr)
        return rows(task, reused=False)


def _diagnose(task: Task) -> None:
    from ..cli.diagnose import diagnose_recording, options_from_args
    from ..cli.options import Problem, prepare
    from ..cli.per_joint import diagnose_each_joint

    # The command line takes recordings as a list (stacked segments); a task is one of them.
    args = argparse.Namespace(**{**task.arguments, "recording": [task.arguments["recording"]]}, out=task.out,
                              input_hash=task.input_hash)
    options = options_from_args(args)
    out, problem = prepare(args)
    quiet = lambda message: None  # noqa: E731 (the fleet reports progress per recording)
    if isinstance(problem, Problem):
        diagnose_recording(args, out, problem, options, quiet)
    else:
        diagnose_each_joint(args, out, problem, options, quiet)


def failed_row(task: Task, error: str, seconds: float) -> dict:
    row = dict.fromkeys(FIELDS, "")
    row.update(recording=task.name, status="failed", seconds=round(seconds, 3), reused=0,
               error=" ".join(error.split()))
    return row


def rows(task: Task, reused: bool) -> list[dict]:
    """One row per joint from the task's complete report folder."""
    data = json.loads((task.out / "diagnosis.json").read_text(encoding="utf-8"))
    joints = data["joints"] if "joints" in data else {"1": data}
    out = []
    for j, d in joints.items():
        folder = task.out / f"joint{j}" if "joints" in data else task.out
        run = json.loads((folder / MARKER).read_text(encoding="utf-8"))
        row = dict.fromkeys(FIELDS, "")
        row.update(recording=task.name, joint=int(j), status="ok", verdict=d["verdict"],
                   missing=";".join(d["missing"]), explained=d.get("explained", ""), seconds=run["seconds"],
                   reused=int(reused), report=(folder / "index.html").relative_to(task.out.parent).as_posix())
        for when, fit in (("before", d["initial_fit"]), ("after", d["final_fit"])):
            for s, v in fit["nrmse_heldout"].items():
                if s in SIGNAL_ORDER:
                    row[f"nrmse_{when}_{s}"] = v
        out.append(row)
    return out
