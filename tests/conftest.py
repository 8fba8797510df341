"""Session-wide test setup: MuJoCo's log goes to a temporary folder, never into the tree.

MuJoCo appends every warning (an unstable state: "Nan, Inf or huge value in QACC", ...) to
``MUJOCO_LOG.TXT`` in the working directory. Tests that drive a model to divergence on
purpose, or call ``mujoco.rollout`` without ``mujoco_log_silenced``, would leave that file in
the repository root; the session points the log at a temporary file instead, and fails if
the root's log appeared or grew anyway (a subprocess started in the root, say).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path


def _avx512_kernels() -> None:
    """Run OpenBLAS's AVX-512 kernels wherever the processor has them, before numpy loads.

    Some of the diagnosis's paths hang on the last bits of the linear algebra: the README's route
    takes different paths with OpenBLAS's AVX-512, Haswell and Sandybridge kernels on one
    processor (docs/diagnosis.md, "The README's route, measured"). Where the processor has
    AVX-512 the suite runs its own kernels, not the Haswell ones some environments force
    (``OPENBLAS_CORETYPE``); elsewhere the Haswell kernels OpenBLAS picks itself.
    """
    try:
        flags = Path("/proc/cpuinfo").read_text()
    except OSError:
        return
    if "numpy" not in sys.modules and " avx512f " in flags:
        os.environ["OPENBLAS_CORETYPE"] = "SkylakeX"


def _a_share_of_the_cores() -> None:
    """Under pytest-xdist each worker runs on its own share of the cores, before numpy loads.

    A fit's rollouts run one thread per core the process may use (``identify.windows``), and
    OpenBLAS sizes its pool the same way: with every worker seeing every core, n workers run n
    times as many threads as there are cores, and each rollout waits at its end for the thread
    that was put aside. The suite's expectations hold at either thread count.
    """
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    count = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0"))
    if not worker.startswith("gw") or count < 2 or not hasattr(os, "sched_setaffinity"):
        return
    cores = sorted(os.sched_getaffinity(0))
    index = int(worker[2:])
    if len(cores) >= count and index < count:
        os.sched_setaffinity(0, cores[index * len(cores) // count:(index + 1) * len(cores) // count])


_avx512_kernels()
_a_share_of_the_cores()

import mujoco  # noqa: E402  (numpy loads with it: after the kernels are chosen)
import pytest  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ROOT_LOG = ROOT / "MUJOCO_LOG.TXT"


def _log_state() -> tuple[int, int] | None:
    return (ROOT_LOG.stat().st_size, ROOT_LOG.stat().st_mtime_ns) if ROOT_LOG.exists() else None


def pytest_sessionstart(session: pytest.Session) -> None:
    session.config.stash[_ROOT_LOG_KEY] = _log_state()


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    if _log_state() != session.config.stash.get(_ROOT_LOG_KEY, None):
        print(f"\nFAILED: the tests wrote {ROOT_LOG} (MuJoCo warnings); run them with a temporary "
              "log or working directory (tests/conftest.py)")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


_ROOT_LOG_KEY = pytest.StashKey[tuple[int, int] | None]()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Files marked ``long(minutes)`` run first, the longest first: a worker takes a whole file
    (``--dist loadfile``, in collection order), and a long file started late runs on alone after
    the others are done."""
    def minutes(item: pytest.Item) -> float:
        mark = item.get_closest_marker("long")
        return -mark.args[0] if mark is not None else 0.0
    items.sort(key=minutes)


@pytest.fixture(autouse=True, scope="session")
def mujoco_log_file(tmp_path_factory) -> Path:
    """Where MuJoCo writes its log during the tests (a temporary file)."""
    config = mujoco.MjLogConfig.get()
    previous = config.logfile
    config.logfile = str(tmp_path_factory.mktemp("mujoco") / "MUJOCO_LOG.TXT")
    config.set()
    yield Path(config.logfile)
    config = mujoco.MjLogConfig.get()
    config.logfile = previous
    config.set()


@pytest.fixture(autouse=True)
def _mujoco_warnings_to_the_log() -> None:
    """Importing dm_control routes MuJoCo's warnings to its own callback for the whole process
    (collecting a test file that imports it is enough): each test starts with them going to the
    log, whichever files ran before it in its process."""
    mujoco.set_mju_user_warning(None)
