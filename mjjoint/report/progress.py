"""Progress on stderr while fitting, so stdout carries only the summary.

On a terminal an LM fit shows a tqdm bar (iteration and objective); in a log or a pipe every
iteration is one plain line, which stays readable where a redrawn bar would not.
"""
from __future__ import annotations

import sys
import time
from typing import TextIO

from tqdm import tqdm


class FitProgress:
    """``progress(iteration, objective)`` callback of ``identify.fit``; use as a context manager."""

    def __init__(self, total: int, desc: str = "fit", stream: TextIO | None = None):
        self.stream = stream or sys.stderr
        self.desc = desc
        self.bar = tqdm(total=total, desc=desc, unit="it", file=self.stream, leave=False) \
            if self.stream.isatty() else None

    def __call__(self, iteration: int, objective: float) -> None:
        if self.bar is not None:
            self.bar.update(iteration - self.bar.n)
            self.bar.set_postfix_str(f"objective {objective:.5g}")
        else:
            print(f"{self.desc}: iteration {iteration}, objective {objective:.5g}", file=self.stream, flush=True)

    def __enter__(self) -> "FitProgress":
        return self

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.close()


class StepLog:
    """``progress(message)`` callback of ``diagnose``: each message with the elapsed time."""

    def __init__(self, stream: TextIO | None = None):
        self.stream = stream or sys.stderr
        self.start = time.perf_counter()

    def __call__(self, message: str) -> None:
        print(f"[{time.perf_counter() - self.start:7.1f} s] {message}", file=self.stream, flush=True)
