"""Hysteretic nonlinear stiffness: Bouc-Wen state with polynomial hardening (Eqs. 16-17).

    Gamma(delta, x) = sum_i [ mu k_i sgn(delta)|delta|^i + (1-mu) k_i sgn(x)|x|^i ]   (16)
(sgn(v)|v|^i is written v, v|v|, v^3 for i = 1, 2, 3.)
    x' = A delta' - beta |delta'| |x|^{n-1} x - gamma delta' |x|^n                      (17)

(17) is rate independent, dx = [A - (beta sgn(d delta) sgn(x) + gamma)|x|^n] d delta, so the
plugin steps it with the deflection increment of the step rather than a time derivative,
linearly implicitly in x (one Newton step of backward Euler), in pieces of at most x_u/10:
the plastic branch saturates x at x_u = (A/(beta+gamma))^{1/n} without overshoot.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import check
from .jit import kernel
from .term import Term


@kernel
def restoring_torque(delta: float, x: float, mu: float, k1: float, k2: float, k3: float) -> float:
    """Gamma(delta, x) of Eq. 16 for the cubic stiffness polynomial k1, k2, k3."""
    elastic = k1 * delta + k2 * delta * abs(delta) + k3 * delta * delta * delta
    plastic = k1 * x + k2 * x * abs(x) + k3 * x * x * x
    return mu * elastic + (1.0 - mu) * plastic


@kernel
def _boucwen_newton(x: float, dd: float, a: float, beta: float, gamma: float, n: float) -> float:
    """One Newton step of backward Euler x' = x + dd g(x') over a small increment dd."""
    sd = 1.0 if dd > 0.0 else -1.0
    sx = 1.0 if x > 0.0 else (-1.0 if x < 0.0 else sd)  # at x = 0 the step enters the sd branch
    ax = abs(x)
    c = beta * sd * sx + gamma
    if n == 1.0:  # the usual case, without pow()
        g = a - c * ax
        dg = -c * sx
    else:
        g = a - c * ax ** n
        dg = -n * c * sx * ax ** (n - 1.0) if ax > 0.0 else 0.0
    return x + dd * g / (1.0 - dd * dg)


@kernel
def boucwen_step(x: float, ddelta: float, a: float, beta: float, gamma: float, n: float) -> float:
    """Advance the Bouc-Wen state x over a deflection increment ``ddelta`` (Eq. 17).

    The increment is split so that each piece moves x by at most a tenth of the saturation
    value x_u (one piece in the plugin's normal use: a step's deflection change is far below
    that), which keeps x inside [-x_u, x_u] for any increment.
    """
    if ddelta == 0.0:
        return x
    s = beta + gamma
    pieces = 1
    # n = 1: x_u = A/s, so one piece suffices while |ddelta| s < 0.1, the plugin's every step
    # (the test below without its three divisions).
    if s > 0.0 and not (n == 1.0 and abs(ddelta) * s < 0.1):
        xu = a / s if n == 1.0 else (a / s) ** (1.0 / n)
        pieces = min(int(abs(ddelta) * a / (0.1 * xu)) + 1, 10000)
    if pieces == 1:
        return _boucwen_newton(x, ddelta, a, beta, gamma, n)
    dd = ddelta / pieces
    for _ in range(pieces):
        x = _boucwen_newton(x, dd, a, beta, gamma, n)
    return x


@dataclass(frozen=True)
class BoucWen:
    """Bouc-Wen shape parameters; ``mu`` weights elastic (1) against plastic (0) deflection.

    Defaults give an elastic-plastic transition at x_u = (A/(beta+gamma))^{1/n} = 2 mrad of
    link-side deflection (harmonic drives of this size reach their rated torque at a few
    mrad), with a moderate loop (mu = 0.7, Fig. 9 (b)-like).
    """

    mu: float = 0.7       # elastic share (Eq. 16); Fig. 9 shows 1, 0.5, 0.1
    a: float = 1.0        # A: initial slope dx/d delta; 1 makes x follow delta in the elastic range
    beta: float = 250.0   # beta [1/rad^n]: with gamma, x_u = 1/(beta+gamma) = 2 mrad for n = 1
    gamma: float = 250.0  # gamma [1/rad^n]: beta = gamma gives the classic symmetric loop
    n: float = 1.0        # smoothness of the elastic-plastic transition (n >= 1)

    def __post_init__(self) -> None:
        check("mu", self.mu, 0.0, 1.0)
        check("a", self.a, 0.0, lo_open=True)
        check("beta", self.beta, 0.0)
        check("gamma", self.gamma, -self.beta, self.beta)
        check("n", self.n, 1.0, 10.0)

    @property
    def x_ultimate(self) -> float:
        """Saturation value of x on the loading branch, (A/(beta+gamma))^{1/n}."""
        s = self.beta + self.gamma
        return float("inf") if s <= 0 else (self.a / s) ** (1.0 / self.n)


def _steady(bw: BoucWen, motion):
    """x on the loading branch: the deflection, saturated at x_u."""
    xu = (bw.a / max(bw.beta + bw.gamma, 1e-300)) ** (1.0 / bw.n)
    return {"x": np.clip(motion["delta"], -xu, xu)}


# Without hysteresis the spring is purely elastic: mu = 1.
TERM = Term(section="hysteresis", kinds={"boucwen": BoucWen}, site="gear",
            doc="Bouc-Wen hysteretic share of the gear stiffness (Eqs. 16-17)",
            states=("x",), absent={"mu": 1.0}, nested_in="transmission", steady=_steady)
