"""The user's limits on a designed experiment, and their check on a simulated run.

Torque is bounded by construction (every input family scales its programme to ``max_torque``);
speed and angle depend on the plant, so they are penalised during the search and verified on
each rival's simulated run before anything is exported (``violations``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import check

SIGNALS = ("q", "theta", "tau")
# A recorded signal -> the windowed prediction it is compared as: theta as the deflection
# delta = q / N - theta, as the fits do.
PREDICTED = {"q": "q", "theta": "delta", "tau": "tau"}


@dataclass(frozen=True)
class Limits:
    """What the experiment may do: peak motor torque |u| [N m], peak motor speed |dq/dt|
    [rad/s], link excursion |theta - theta(0)| [rad], its length [s], the sampling rate [Hz]
    and the signals the new recording will hold."""

    max_torque: float = 0.2
    max_speed: float = 50.0
    angle_range: float = 0.5
    duration: float = 5.0
    rate: float = 1000.0
    signals: tuple[str, ...] = SIGNALS

    def __post_init__(self) -> None:
        check("max_torque", self.max_torque, 0.0, lo_open=True)
        check("max_speed", self.max_speed, 0.0, lo_open=True)
        check("angle_range", self.angle_range, 0.0, lo_open=True)
        check("duration", self.duration, 2.5, 600.0)  # the windows need at least 8 x 0.25 s
        check("rate", self.rate, 10.0, 1e5)
        unknown = [s for s in self.signals if s not in SIGNALS]
        if not self.signals or unknown:
            raise ValueError(f"signals={','.join(self.signals) or '(none)'} must be a non-empty subset of "
                             f"{','.join(SIGNALS)}")

    @property
    def samples(self) -> int:
        return int(round(self.duration * self.rate))


def _peaks(trace, limits: Limits):
    """(name, peak of the run, its limit, unit) for each limit."""
    return (("torque", float(np.max(np.abs(trace.u))), limits.max_torque, "N m"),
            ("motor speed", float(np.max(np.abs(trace.qd))), limits.max_speed, "rad/s"),
            ("link excursion", float(np.max(np.abs(trace.theta - trace.theta[0]))), limits.angle_range, "rad"))


def shares(trace, limits: Limits, margin: float = 1.0) -> dict[str, float]:
    """Per limit, the share of it a simulated run uses (1: on the limit; > 1: past it), the
    plant-dependent ones (speed, excursion) taken as ``margin`` times their limit; the torque is
    what is commanded, exact."""
    return {name: value / (limit if name == "torque" else margin * limit)
            for name, value, limit, _ in _peaks(trace, limits)}


def usage(trace, limits: Limits, margin: float = 1.0) -> float:
    """The largest share of a limit a simulated run uses (``shares``)."""
    return max(shares(trace, limits, margin).values())


def violations(trace, limits: Limits, who: str) -> list[str]:
    """One line per limit the run ``trace`` exceeds (empty: within every limit)."""
    return [f"{who}: {name} {value:.4g} {unit} exceeds the limit {limit:g} {unit}"
            for name, value, limit, unit in _peaks(trace, limits) if value > limit * (1 + 1e-9)]
