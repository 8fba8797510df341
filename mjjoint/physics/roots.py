"""The root of an increasing scalar function inside a bracket, as the dry-friction steps solve
for the velocity a step ends with (``stribeck.static_friction_step``, ``load.bearing_step``)."""
from __future__ import annotations

from .jit import kernel

# Bisection alone narrows a bracket to 1e-24 of its width in 80 steps: the cap for a root at an
# end of the bracket that is 0, which no relative test can declare found.
ITERATIONS = 80


@kernel
def newton_in_bracket(w: float, g: float, dg: float, lo: float, hi: float):
    """One safeguarded Newton step at w, where the function is g and its slope dg: the bracket
    shrinks to the side of the root (g > 0: it lies below w), then the Newton point is taken if
    it falls inside, else the bracket's midpoint. Returns (next w, lo, hi, converged: the step
    or the bracket within 1e-15 of the root's size)."""
    if g == 0.0:
        return w, lo, hi, True
    if g > 0.0:
        hi = w
    else:
        lo = w
    nxt = w - g / dg if dg > 0.0 else 0.5 * (lo + hi)
    if not lo <= nxt <= hi:
        nxt = 0.5 * (lo + hi)
    return nxt, lo, hi, abs(nxt - w) <= 1e-15 * abs(nxt) or hi - lo <= 1e-15 * max(abs(lo), abs(hi))
