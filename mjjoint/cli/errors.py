"""User errors on the command line: one line ``mjjoint: error: ...`` on stderr, exit code 2.

Bad files, unknown keys, out-of-range values and unwritable paths all surface as
``ValueError`` (the parameter dataclasses, model files, recordings) or ``OSError``; the
wrapper turns them into that one line. Any other exception is a bug and keeps its traceback;
``MJJOINT_TRACEBACK=1`` shows the traceback of a user error too.
"""
from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable

from .. import interrupts

PROG = "mjjoint"
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


class CliError(ValueError):
    """A mistake in the command line itself (missing or conflicting options)."""


class ArgumentParser(argparse.ArgumentParser):
    """argparse that raises ``CliError`` instead of printing the usage block and exiting."""

    def error(self, message: str):
        raise CliError(f"{message} (see '{self.prog} --help')")


def describe(exc: BaseException) -> str:
    """The exception as one line of text."""
    if isinstance(exc, OSError) and exc.strerror:
        where = exc.filename if exc.filename is not None else "file"
        return f"{where}: {exc.strerror}"
    return " ".join(str(exc).split()) or type(exc).__name__


def guarded(command: Callable[[], int]) -> int:
    """Run ``command``; a user error is printed as one line and gives exit code 2.

    An interrupt gives exit code 130, also one that Python could only print (``interrupts``).
    """
    start = interrupts.count()
    try:
        with interrupts.counted():
            code = command()
        interrupts.raise_if_interrupted(start)
        return code
    except SystemExit as exc:  # argparse's --help
        return exc.code if isinstance(exc.code, int) else 0 if exc.code is None else 1
    except (ValueError, OSError) as exc:
        if os.environ.get("MJJOINT_TRACEBACK"):
            raise
        print(f"{PROG}: error: {describe(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
