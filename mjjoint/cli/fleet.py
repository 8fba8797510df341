"""``mjjoint diagnose`` on a fleet: a folder, a glob or a manifest of recordings, each on its own.

Every recording is diagnosed as ``mjjoint diagnose REC --out DIR/<name>`` would (its options
from the command line, replaced by its manifest row's), on a local process pool or on a Dask
cluster (``--scheduler``). DIR/fleet.csv has one row per recording and joint, DIR/index.html
links the reports. A recording that fails gives a failed row and the others go on; the exit
code is then 1. A rerun keeps each report whose inputs and options are unchanged
(``fleet.task.finished``); ``--force`` redoes them.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from ..fleet import engines
from ..fleet.inputs import Entry, resolve
from ..fleet.task import FIELDS, Task, finished, input_hash, rows
from ..problem import check_inputs
from ..report.output import check_folder
from .errors import CliError
from .options import NAMES, PLANTS, inputs_from_args, joint_numbers, numbers

EXIT_FAILED = 1
FLEET_MARK = ".mjjoint-fleet"  # an (empty) file naming DIR a fleet folder, so a rerun may write into it
RUN_ONLY = ("handler", "command", "out", "workers", "scheduler", "force")


def add_fleet_options(p: argparse.ArgumentParser) -> None:
    f = p.add_argument_group("fleet (REC a folder, a quoted glob, or a manifest .toml/.csv; docs/fleet.md)")
    f.add_argument("--workers", type=int, metavar="N",
                   help="local processes diagnosing recordings side by side (default: one per core; 1: in this process)")
    f.add_argument("--scheduler", metavar="ADDR",
                   help="a Dask scheduler (tcp://host:port) whose workers do the work instead; they read the "
                        "recordings and write DIR on a shared path")
    f.add_argument("--force", action="store_true", help="diagnose again recordings whose report is up to date")


def check_single(args: argparse.Namespace) -> None:
    """Fleet options with one recording are a mistake worth naming."""
    # by identity: --workers 0 equals False
    given = [f"--{k}" for k in ("workers", "scheduler", "force") if (v := getattr(args, k)) is not None and v is not False]
    if given:
        raise CliError(f"{', '.join(given)}: for a folder, glob or manifest of recordings; "
                       f"{' '.join(map(str, args.recording))} is not a fleet")


def _flag(text: str) -> bool:
    if text.lower() in ("true", "1", "yes"):
        return True
    if text.lower() in ("false", "0", "no", ""):
        return False
    raise ValueError(f"{text!r} is not true or false")


def _plant(text: str) -> str:
    if text not in PLANTS:
        raise ValueError(f"{text!r} is not one of {', '.join(PLANTS)}")
    return text


# A manifest's text -> what the command-line option holds.
CONVERT = {"gear_ratio": numbers, "k_m": numbers, "joint": joint_numbers, "model": Path, "allow_gaps": _flag,
           "plant": _plant, "columns": str, "scales": str, "base": str}


def _arguments(args: argparse.Namespace, entry: Entry) -> dict:
    arguments = {k: v for k, v in vars(args).items() if k not in RUN_ONLY}
    for key, text in entry.options.items():
        try:
            arguments[key] = CONVERT[key](text)
        except (ValueError, argparse.ArgumentTypeError) as exc:
            raise CliError(f"recording {entry.name}: {key} {exc}") from None
    if "model" in entry.options:  # the row's starting model replaces the command line's, either kind
        arguments["base"] = entry.options.get("base")
    elif "base" in entry.options:
        arguments["model"] = None
    arguments["recording"] = entry.path.absolute()
    if arguments["model"] is not None:
        arguments["model"] = Path(arguments["model"]).absolute()
    try:  # what the row's own run would refuse before reading its recording, refused now
        check_inputs(inputs_from_args(argparse.Namespace(**arguments)), NAMES)
    except (ValueError, argparse.ArgumentTypeError) as exc:
        raise CliError(f"recording {entry.name}: {exc}") from None
    return arguments


def _engine(args: argparse.Namespace, tasks: list[Task]) -> tuple[engines.Done, str]:
    if args.scheduler is not None:
        client = engines.connect(args.scheduler)
        return engines.dask_cluster(tasks, client), f"the Dask cluster at {args.scheduler}"
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    workers = min(args.workers or cores, max(1, len(tasks)))
    if workers == 1:
        return engines.serial(tasks), "this process"
    return engines.process_pool(tasks, workers), f"{workers} local processes"


def _duration(seconds: float) -> str:
    minutes, s = divmod(round(seconds), 60)
    return f"{minutes} min {s} s" if minutes else f"{s} s"


def _kept(task: Task) -> list[dict] | None:
    """The rows of the task's report from an earlier run, if it is finished and readable."""
    if not finished(task):
        return None
    try:
        return rows(task, reused=True)
    except (OSError, ValueError, KeyError):  # damaged by hand: diagnose it again
        return None


def _collect(done: engines.Done, n: int, results: dict[str, list[dict]]) -> None:
    """Each recording's rows as it finishes, with a progress line and the time left at this rate."""
    start = time.perf_counter()
    for k, (task, task_rows) in enumerate(done, 1):
        results[task.name] = task_rows
        elapsed = time.perf_counter() - start
        status = "ok" if task_rows[0]["status"] == "ok" else f"failed: {task_rows[0]['error']}"
        left = f"; about {_duration(elapsed / k * (n - k))} left" if k < n else ""
        print(f"recording {k} of {n}: {task.name} {status} ({_duration(elapsed)} elapsed{left})",
              file=sys.stderr, flush=True)


def run_fleet(args: argparse.Namespace, spec: Path) -> int:
    """Diagnose every recording of the fleet ``spec`` (folder, glob or manifest); write
    DIR/fleet.csv and DIR/index.html."""
    from ..report.fleet import CSV_NAME, write_fleet

    if args.workers is not None and args.workers < 1:
        raise CliError(f"--workers {args.workers} must be at least 1")
    if args.workers is not None and args.scheduler is not None:
        raise CliError("--workers is for the local pool; with --scheduler the cluster's workers do the work")
    out = Path(args.out).absolute()
    check_folder(out, FLEET_MARK, "an mjjoint fleet output")
    tasks = []
    for entry in resolve(spec):
        arguments = _arguments(args, entry)
        tasks.append(Task(entry.name, arguments, out / entry.name, input_hash(arguments)))
    results = {t.name: kept for t in tasks if not args.force and (kept := _kept(t)) is not None}
    todo = [t for t in tasks if t.name not in results]
    start = time.perf_counter()
    done, where = _engine(args, todo) if todo else (iter(()), "nothing")
    out.mkdir(parents=True, exist_ok=True)  # only now: a refused fleet or scheduler leaves nothing
    (out / FLEET_MARK).touch()
    kept = f"; {len(results)} up to date from an earlier run (--force redoes them)" if results else ""
    print(f"diagnosing {len(todo)} of {len(tasks)} recordings on {where}{kept}", file=sys.stderr, flush=True)
    _collect(done, len(todo), results)
    failed = [t.name for t in tasks if results[t.name][0]["status"] == "failed"]
    reused = len(tasks) - len(todo)
    summary = (f"{len(tasks)} recordings: {len(tasks) - len(failed)} ok"
               + (f" ({reused} from an earlier run)" if reused else "")
               + (f", {len(failed)} failed ({', '.join(failed)})" if failed else ""))
    run = {"command": "diagnose", "recordings": [t.recording for t in tasks], "engine": where,
           "arguments": {**{k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items() if k != "handler"},
                         "recording": str(spec)},
           "seconds": round(time.perf_counter() - start, 3), "summary": summary}
    write_fleet(out, FIELDS, [r for t in tasks for r in results[t.name]], str(spec), run)
    print(f"fleet: {summary}")
    print(f"report: {out / 'index.html'}  (rows: {CSV_NAME}; each recording's report in its own folder)")
    return EXIT_FAILED if failed else 0
