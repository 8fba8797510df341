"""Gear laws of the independent plant (link side, delta = q/N - theta, as Eq. 5 implies).

* Dead zone of total width b (backlash, Fig. 3 (a)): the engaged deflection is delta -+ b/2
  outside the gap and no torque passes inside it.
* Bouc-Wen (Eqs. 16-17, linear stiffness, n = 1): T = mu k de + (1 - mu) k x,
  dx/dt = A de' - beta |de'| x - gamma de' |x|.
* Prandtl-Ishlinskii (a different hysteresis law): T = k_e de + sum_i w_i P_ri(de), each P_r a
  play operator of half-width r_i; piecewise linear loops with sharp corners, no Bouc-Wen
  shape.
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


@dataclass(frozen=True)
class PlayHysteresis:
    """Prandtl-Ishlinskii: elastic share k_e, play operators (half-widths r_i, weights w_i)."""

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
        return self.elastic * de + float(np.dot(self.weights, p))
