"""Ctrl-C that is never lost: counted, so that output is not put in place after one.

Python turns SIGINT into KeyboardInterrupt wherever the main thread is; raised inside a
finalizer or weakref callback it is only printed ("Exception ignored in ...") and the run goes
on. While ``counted()`` is active every SIGINT is counted before it is raised, such lost ones
are not printed, and ``raise_if_interrupted(since)`` raises for any interrupt after ``since``.
"""
from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_count = 0


def count() -> int:
    """SIGINTs received so far under ``counted()``."""
    return _count


def raise_if_interrupted(since: int) -> None:
    """Raise KeyboardInterrupt if a SIGINT arrived after ``count()`` was ``since``."""
    if _count > since:
        raise KeyboardInterrupt


def _on_sigint(signum, frame):
    global _count
    _count += 1
    raise KeyboardInterrupt


def _unraisable(hook):
    def quiet(unraisable):
        if not isinstance(unraisable.exc_value, KeyboardInterrupt):  # counted already
            hook(unraisable)
    return quiet


@contextmanager
def counted() -> Iterator[None]:
    """Count SIGINTs (main thread only; elsewhere signals cannot be handled)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous, hook = signal.signal(signal.SIGINT, _on_sigint), sys.unraisablehook
    sys.unraisablehook = _unraisable(hook)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = hook
