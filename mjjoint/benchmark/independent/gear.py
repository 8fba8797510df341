"""Gear laws of the independent plant (link side, delta = q/N - theta, as Eq. 5 implies).

* Dead zone of total width b (backlash, Fig. 3 (a)): the engaged deflection is delta -+ b/2
  outside the gap and no torque passes inside it.
* Bouc-Wen (Eqs. 16-17, linear stiffness, n = 1): T = mu k de + (1 - mu) k x,
  dx/dt = A de' - beta |de'| x - gamma de' |x|.
* Prandtl-Ishlinskii of stop type (a different hysteresis law; an Iwan gear): T = k_e de +
  sum_i w_i S_ri(de), S_r(de) = de - P_r(de) the stop operator, P_r the play operator of
  half-width r: elastic-perfectly-plastic elements (a spring w_i behind a slider that gives at
  w_i r_i) beside a spring k_e. Piecewise linear loops with sharp corners, no Bouc-Wen shape.
  The play operators alone beside a spring (T = k_e de + sum w_i P_ri(de)) would run each loop
  the other way round and give energy back: not a passive gear.

Each law's ``stored`` energy grows by no more than the work the torque does on the deflection:
the loops dissipate (``tests/test_outside_plant.py``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def dead_zone(delta: float, width: float) -> float:
    half = 0.5 * width
    if delta > half:
        return delta - half
    if delta < -half:
        return delta + half
    return 0.0


@dataclass(frozen=True)
class BoucWenLaw:
    mu: float            # elastic share
    a: float = 1.0
    beta: float = 500.0  # [1/rad]: x saturates at A / (beta + gamma)
    gamma: float = 0.0

    def rate(self, dde: float, x: float) -> float:
        return self.a * dde - self.beta * abs(dde) * x - self.gamma * dde * abs(x)

    def torque(self, k: float, de: float, x: float) -> float:
        return self.mu * k * de + (1.0 - self.mu) * k * x

    def stored(self, k: float, de: float, x: float) -> float:
        """mu k de^2 / 2 + (1 - mu) k x^2 / (2 A): its rate is the power T de' less
        (1 - mu) k (beta |de'| x^2 + gamma de' x |x|) / A, which beta >= |gamma| keeps >= 0."""
        return 0.5 * self.mu * k * de * de + 0.5 * (1.0 - self.mu) * k * x * x / self.a


@dataclass(frozen=True)
class StopHysteresis:
    """Prandtl-Ishlinskii of stop type: elastic share k_e, elastic-plastic elements (yield
    half-widths r_i, stiffnesses w_i). The states are the sliders' positions p_i, the play
    operators' outputs; each element's spring is stretched by de - p_i, at most r_i."""

    elastic: float                # [N m/rad]
    radii: tuple[float, ...]      # [rad]
    weights: tuple[float, ...]    # [N m/rad]

    def rates(self, dde: float, de: float, p: np.ndarray) -> np.ndarray:
        """dp_i/dt: an operator's output follows its input once the input sits on an edge."""
        r = np.asarray(self.radii)
        moving = ((de - p >= r) & (dde > 0)) | ((de - p <= -r) & (dde < 0))
        return np.where(moving, dde, 0.0)

    def clip(self, de: float, p: np.ndarray) -> np.ndarray:
        r = np.asarray(self.radii)
        return np.clip(p, de - r, de + r)

    def torque(self, de: float, p: np.ndarray) -> float:
        return self.elastic * de + float(np.dot(self.weights, de - p))

    def stored(self, de: float, p: np.ndarray) -> float:
        return 0.5 * self.elastic * de * de + 0.5 * float(np.dot(self.weights, (de - p) ** 2))
