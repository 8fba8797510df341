"""Quiet MuJoCo's own log while mjjoint handles instability itself."""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import mujoco


@contextmanager
def mujoco_log_silenced() -> Iterator[None]:
    """Keep MuJoCo's log (console and MUJOCO_LOG.TXT) quiet; restored afterwards.

    Its one warning on mjjoint's paths, an unstable state, is detected by the caller
    (``sim.check_diverged``, or NaN residuals while fitting) and reported once, in one line.
    """
    previous = mujoco.MjLogConfig.get()
    quiet = mujoco.MjLogConfig.get()
    quiet.logto_console = quiet.logto_file = False
    quiet.set()
    try:
        yield
    finally:
        previous.set()
