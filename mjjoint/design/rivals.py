"""The two explanations an experiment must separate, each a fitted structure with its intervals.

A rival is named by the effect that distinguishes it (``input_offset``, ``friction_asymmetry``,
...) over a base both share. Its parameter uncertainty enters the design as prediction spread:
``draws`` gives a few structures drawn about the fitted one, in the optimiser's coordinates
(log where a parameter spans decades), with the standard error each 95 % interval implies.
Only the distinguishing effect's parameters are drawn: the intervals are marginal (the fit keeps
no covariance), and drawing correlated base parameters independently (inertia and stiffness,
Coulomb and viscous friction) would spread predictions along directions the fit pins down.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..identify.effects import EFFECTS
from ..identify.structure import Structure

Z95 = 1.959964  # half-width of a 95 % interval in standard errors


@dataclass(frozen=True)
class Rival:
    """One explanation: the effect that distinguishes it, its fitted structure, its 95 % intervals."""

    effect: str
    structure: Structure
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.effect not in self.structure.effects:
            raise ValueError(f"rival {self.effect!r} is not among its structure's effects "
                             f"({', '.join(self.structure.effects)})")

    @property
    def drawn(self) -> tuple[str, ...]:
        """The parameters whose uncertainty is propagated: the distinguishing effect's."""
        own = {p.name for p in EFFECTS[self.effect].params}
        return tuple(p.name for p in self.structure.params if p.name in own)

    def standard_errors(self, names=None) -> np.ndarray:
        """Standard error of each of ``names`` (default the drawn parameters) in the optimiser's
        coordinates, from its 95 % interval; no interval or an unbounded one: a quarter of the
        parameter's range."""
        names = self.drawn if names is None else tuple(names)
        lo, hi = self.structure.bounds(names)
        params = {p.name: p for p in self.structure.params}
        se = []
        for name, a, b in zip(names, lo, hi):
            span = (b - a) / 4
            if name in self.intervals:
                p = params[name]
                low, high = self.intervals[name]
                if p.log and low <= 0:
                    se.append(span)
                    continue
                width = abs(p.to_unit(high) - p.to_unit(low)) / (2 * Z95)
                se.append(min(width, span) if np.isfinite(width) else span)
            else:
                se.append(span)
        return np.asarray(se)

    def draws(self, n: int, seed: int = 0, names=None) -> list[Structure]:
        """``n`` structures (n even: antithetic pairs x +- d, so the draws' mean is the fit)
        with the parameters ``names`` (default the drawn ones) normal about the fit, clipped to
        their bounds."""
        names = self.drawn if names is None else tuple(names)
        if n == 0 or not names:
            return []
        x = self.structure.vector(names)
        se = self.standard_errors(names)
        lo, hi = self.structure.bounds(names)
        d = np.random.default_rng(seed).standard_normal(((n + 1) // 2, len(names))) * se
        steps = np.concatenate([d, -d])[:n]
        return [self.structure.from_vector(np.clip(x + s, lo, hi), names) for s in steps]

    def joint_draws(self, n: int, seed: int = 0) -> list[Structure]:
        """``n`` draws of every parameter, each independently within its interval: for checking
        the limits only. A tying recording can leave shared parameters loose (a motor inertia
        known to a factor of 2), and the truth's run of an input then differs from both rivals'
        (docs/design-experiments.md); independent draws spread wider than the joint
        uncertainty, the safe side for a limit. Only parameters with a finite interval are
        drawn: an unbounded one is a log parameter fitted to its lower bound (no viscous
        friction, say), whose range the recording did not open, only failed to close."""
        finite = [p.name for p in self.structure.params if p.name in self.intervals
                  and np.all(np.isfinite(self.intervals[p.name]))
                  and (not p.log or self.intervals[p.name][0] > 0)
                  and abs(p.to_unit(self.intervals[p.name][1]) - p.to_unit(self.intervals[p.name][0])) < np.inf]
        return self.draws(n, seed, finite)

    def describe(self) -> dict:
        return {"effect": self.effect, **self.structure.describe(),
                "intervals_95": {k: list(v) for k, v in self.intervals.items()}}
