"""Run a fleet's tasks: in this process, on a local process pool, or on a Dask cluster.

Each engine yields ``(task, rows)`` as tasks finish, in completion order. A task's own errors
come back as a failed row from ``run_task``; what kills a worker (a crash, a lost machine) is
turned into a failed row here, so one recording never ends the fleet.

Pool processes are spawned, not forked: a fork would copy this process's MuJoCo and numba
state and any threads it holds, which is not safe to continue in the child.
"""
from __future__ import annotations

import multiprocessing
from collections.abc import Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed

from .task import Task, failed_row, run_task

Done = Iterator[tuple[Task, list[dict]]]


def _lost(task: Task, exc: BaseException) -> list[dict]:
    from ..cli.errors import describe
    return [failed_row(task, f"worker lost ({type(exc).__name__}: {describe(exc)})", 0.0)]


def serial(tasks: Sequence[Task]) -> Done:
    for task in tasks:
        yield task, run_task(task)


def process_pool(tasks: Sequence[Task], workers: int) -> Done:
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))
    try:
        futures = {pool.submit(run_task, t): t for t in tasks}
        for future in as_completed(futures):
            task = futures[future]
            try:
                yield task, future.result()
            except Exception as exc:
                yield task, _lost(task, exc)
    finally:
        # An interrupt or error here: queued recordings are dropped, running ones end with
        # their own SIGINT (same process group) and clean up their partial folders.
        pool.shutdown(wait=True, cancel_futures=True)


def connect(address: str):
    """A Dask client of the scheduler at ``address``; one-line errors without dask or the scheduler."""
    try:
        from distributed import Client
    except ImportError:
        raise ValueError("--scheduler needs dask.distributed: pip install 'mjjoint[fleet]'") from None
    try:
        return Client(address, timeout="10s")
    except (OSError, ValueError) as exc:
        raise ValueError(f"--scheduler {address}: cannot connect ({exc})") from None


def dask_cluster(tasks: Sequence[Task], client) -> Done:
    """The tasks on the cluster of ``client`` (from ``connect``), which is closed at the end."""
    from distributed import as_completed as dask_completed

    # Keys name the recording and its inputs: a rerun with new inputs is a new computation.
    futures = {client.submit(run_task, t, key=f"mjjoint-diagnose-{t.name}-{t.input_hash[:16]}", pure=False): t
               for t in tasks}
    try:
        for future in dask_completed(futures):
            task = futures[future]
            try:
                yield task, future.result()
            except Exception as exc:  # KilledWorker, a worker without mjjoint, ...
                yield task, _lost(task, exc)
    finally:
        client.cancel(list(futures))
        client.close()
