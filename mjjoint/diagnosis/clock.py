"""Progress of a diagnosis: round k of K, candidate i of n, an estimate of the time left, and
where the time went (``Phases``)."""
from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Callable


class ScreenClock:
    """Where a diagnosis stands (round k of K, candidate i of n) and the time left, from the mean
    time of the candidate screens so far. Each later round screens one candidate fewer (one is
    added per round); the refits between rounds are not counted, so the estimate is a floor."""

    def __init__(self, rounds: int, phases: "Phases | None" = None):
        self.rounds, self.round = rounds, 1
        self.phases = phases if phases is not None else Phases(lambda: 0.0)
        self.seconds, self.count = 0.0, 0

    def record(self, seconds: float) -> None:
        self.seconds += seconds
        self.count += 1

    def status(self, i: int, n: int) -> str:
        """After candidate i of n of this round: where, and the seconds left (this round, all rounds)."""
        each = self.seconds / max(self.count, 1)
        later = sum(max(n - j, 0) for j in range(1, self.rounds - self.round + 1))
        return (f"round {self.round} of {self.rounds}, candidate {i} of {n}; time left ~{each * (n - i):.0f} s "
                f"this round, ~{each * (n - i + later):.0f} s if all {self.rounds} rounds run")


class Phases:
    """Where a diagnosis's rollouts and wall time went, per phase (base fit, screens, refits, ...).

    ``with phases("name"):`` charges what runs inside to that phase; a phase opened inside
    another is charged to itself alone, so the phases add up to the whole. ``rollouts``: the
    predictor's running count of full-length rollouts."""

    def __init__(self, rollouts: Callable[[], float]):
        self._rollouts = rollouts
        self.spent: dict[str, list[float]] = {}  # phase -> [rollouts, seconds, times entered]
        self._open: list[str] = []
        self._mark = (0.0, 0.0)

    def _charge(self) -> None:
        now = (self._rollouts(), time.perf_counter())
        if self._open:
            row = self.spent.setdefault(self._open[-1], [0.0, 0.0, 0])
            row[0] += now[0] - self._mark[0]
            row[1] += now[1] - self._mark[1]
        self._mark = now

    @contextmanager
    def __call__(self, name: str):
        self._charge()
        self._open.append(name)
        self.spent.setdefault(name, [0.0, 0.0, 0])[2] += 1
        try:
            yield
        finally:
            self._charge()
            self._open.pop()

    def as_dict(self) -> dict[str, dict[str, float]]:
        return {k: {"rollouts": round(r, 1), "seconds": round(s, 2), "count": n} for k, (r, s, n) in self.spent.items()}

    def line(self) -> str:
        return "; ".join(f"{k} {r:.0f} rollouts {s:.1f} s" + (f" ({n}x)" if n > 1 else "")
                         for k, (r, s, n) in self.spent.items())
