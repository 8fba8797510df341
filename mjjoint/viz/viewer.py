"""Open a written .rrd in the Rerun viewer, or say in one line how to view it elsewhere.

The viewer is a desktop window: on a machine without a display (a server, a container, an SSH
session without forwarding) it cannot start. That is found before anything is spawned where
the environment says so (no X11 or Wayland display on Linux); otherwise the viewer is started
on the finished file and given ``START_WAIT`` seconds to fail, quietly (its own log is not the
user's business). Nothing streams over the network, so nothing is lost when no viewer comes.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

START_WAIT = 4.0  # [s] a viewer that cannot open a window exits within ~2 s (measured, Linux)
DISPLAY_VARIABLES = ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET")
VIEWER = (sys.executable, "-m", "rerun")  # the environment's own viewer, whatever PATH holds


def display_problem() -> str | None:
    """Why no viewer window can open here, judged from the environment; None if it may."""
    if sys.platform.startswith(("linux", "freebsd", "openbsd")) and not any(
            os.environ.get(v) for v in DISPLAY_VARIABLES):
        return "no display here (DISPLAY and WAYLAND_DISPLAY are unset)"
    return None


def how_to_view(rrd: Path) -> str:
    return f"view it with 'rerun {rrd}' on a machine with a display"


def open_viewer(rrd: Path, wait: float = START_WAIT) -> str | None:
    """Start the Rerun viewer on ``rrd`` (detached); the reason it could not start, or None."""
    problem = display_problem()
    if problem is not None:
        return problem
    try:
        proc = subprocess.Popen([*VIEWER, str(rrd)], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    except OSError as exc:
        return f"the Rerun viewer could not be started ({exc.strerror or exc})"
    try:
        code = proc.wait(timeout=wait)
    except subprocess.TimeoutExpired:
        return None  # still running: its window is up
    return None if code == 0 else f"the Rerun viewer could not start here (exit code {code})"
