"""Progress of a diagnosis: round k of K, candidate i of n, and an estimate of the time left."""
from __future__ import annotations


class ScreenClock:
    """Where a diagnosis stands (round k of K, candidate i of n) and the time left, from the mean
    time of the candidate screens so far. Each later round screens one candidate fewer (one is
    added per round); the refits between rounds are not counted, so the estimate is a floor."""

    def __init__(self, rounds: int):
        self.rounds, self.round = rounds, 1
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
