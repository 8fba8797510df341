"""Gear transmission: deflection, backlash, hysteretic stiffness and damping (Eqs. 5-8, 16-18).

The deflection is measured on the link side, delta = q/N - theta: Eq. (7) prints N q - theta,
but with the reduction of Eq. (5), theta = q/N, only q/N - theta vanishes for a rigid gear.
The transmitted torque T = Gamma(delta_e, x) + D delta_e' (Eq. 18) acts +T on the link and
-T/N on the motor (Eq. 6). delta_e is the deflection left after a backlash dead zone of total
width ``backlash``; in the gap no torque passes, and D damps only the engaged teeth.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..params import check
from .boucwen import BoucWen, restoring_torque
from .jit import kernel
from .term import Term, nested

# A harmonic drive's deflection at rated torque [rad], where the stability check takes the stiffness.
RATED_DEFLECTION = 5e-3


@kernel
def engaged(delta: float, backlash: float) -> float:
    """Deflection beyond a centred dead zone of total width ``backlash``."""
    half = 0.5 * backlash
    if delta > half:
        return delta - half
    if delta < -half:
        return delta + half
    return 0.0


@kernel
def transmission_torque(delta, ddelta, x, mu, k1, k2, k3, damping, backlash):
    """T = Gamma(delta_e, x) + D delta_e' (Eq. 18) with the backlash dead zone applied."""
    de = engaged(delta, backlash)
    if de == 0.0 and backlash > 0.0:
        return 0.0
    return restoring_torque(de, x, mu, k1, k2, k3) + damping * ddelta


@kernel
def transmission_stiffness(delta_e, x, mu, k1, k2, k3, a):
    """An upper bound of dGamma/d delta (Eq. 16) at the engaged deflection ``delta_e`` and Bouc-Wen
    state x: the elastic part's tangent plus the plastic part's with dx/d delta at its largest, A."""
    elastic = k1 + 2.0 * k2 * abs(delta_e) + 3.0 * k3 * delta_e * delta_e
    plastic = k1 + 2.0 * k2 * abs(x) + 3.0 * k3 * x * x
    return mu * elastic + (1.0 - mu) * a * plastic


# Multi-stage and worm gears reach a few thousand; beyond this a ratio is a typing error, and the
# link's motion (q / N) falls below what a double holds.
MAX_GEAR_RATIO = 1e5


@dataclass(frozen=True)
class Transmission:
    """Gear ratio, stiffness polynomial, damping, backlash and optional Bouc-Wen hysteresis.

    Link-side units: N·m/rad^i for k_i, N·m·s/rad for D, rad for the backlash width.
    ``hysteresis=None`` makes the spring purely elastic (mu = 1, no state); k2 = k3 = 0 then
    gives the linear spring K delta of Eq. (3).
    """

    gear_ratio: float = 160.0     # N: the chapter's harmonic drive (Sec. 4)
    k1: float = 1.0e4             # [N·m/rad]: catalogue order of a size-20 harmonic drive (1e4)
    k2: float = 0.0               # [N·m/rad^2]
    k3: float = 1.0e8             # [N·m/rad^3]: hardening, tangent k1 + 3 k3 d^2 = 1.75e4 (+75 %) at 5 mrad (Sec. 3.3)
    damping: float = 2.0          # D [N·m·s/rad]: ~3 % damping of the ~38 Hz locked-motor mode
    backlash: float = 0.0         # total dead-zone width [rad]; harmonic drives: ~0 (Sec. 2.2)
    hysteresis: BoucWen | None = nested("hysteresis", BoucWen())

    def __post_init__(self) -> None:
        check("gear_ratio", self.gear_ratio, 0.0, MAX_GEAR_RATIO, lo_open=True)
        check("k1", self.k1, 0.0, lo_open=True)
        check("k2", self.k2, 0.0)
        check("k3", self.k3, 0.0)
        check("damping", self.damping, 0.0)
        check("backlash", self.backlash, 0.0, 0.1)

    @property
    def mu(self) -> float:
        return 1.0 if self.hysteresis is None else self.hysteresis.mu

    def torque(self, delta: float, ddelta: float, x: float = 0.0) -> float:
        return transmission_torque(delta, ddelta, x, self.mu, self.k1, self.k2, self.k3,
                                   self.damping, self.backlash)


def _stability(tr: Transmission, motor_inertia: float, link_inertia: float):
    """The spring at ``RATED_DEFLECTION`` and the damper on the reduced inertia of both sides."""
    n = tr.gear_ratio
    d = RATED_DEFLECTION
    k_max = tr.k1 + 2 * tr.k2 * d + 3 * tr.k3 * d * d
    j_red = 1.0 / (1.0 / link_inertia + 1.0 / (motor_inertia * n * n))
    return {"transmission.k1/k3 (stiffness)": k_max / j_red}, {"transmission.damping": tr.damping / j_red}


# Without a transmission the joint is a direct drive: gear ratio 1 and no spring, so T = 0.
TERM = Term(section="transmission", kinds={"spring": Transmission}, site="gear",
            doc="elastic gear: stiffness polynomial, damping and backlash (Eqs. 5-8, 18)",
            absent={"gear_ratio": 1.0}, stability=_stability)
