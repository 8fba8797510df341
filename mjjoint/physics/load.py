"""Load side: bearing friction F_c sgn(theta') + d_f theta' (Sec. 2.3).

Gravity G = l g sin(theta) (Eq. 9) and link flexibility are not written here: they come from
the MJCF bodies (link mass, lever, flexible segments) through MuJoCo's multibody dynamics.

The bearing is dry friction: at rest it holds any torque up to F_c. The joint's scheme
(``coupling.kernels``) takes it at the link velocity the step ends with (``bearing_step``), so
it sticks exactly, at any step, instead of creeping as a regularised sign does.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..params import check
from .jit import kernel
from .roots import ITERATIONS, newton_in_bracket
from .stribeck import smooth_sign
from .term import Term


@kernel
def bearing_friction(w: float, fc: float, viscous: float, v_eps: float) -> float:
    """F_c sgn(w) + d_f w, the sign regularised as tanh(w / v_eps) where v_eps > 0; 0 at w = 0
    (at rest the exact sign is set-valued: ``bearing_step`` decides what the bearing holds)."""
    if v_eps > 0.0:
        sg = smooth_sign(w, v_eps)
    else:
        sg = 1.0 if w > 0.0 else (-1.0 if w < 0.0 else 0.0)
    return fc * sg + viscous * w


@kernel
def bearing_step(v: float, hj: float, fc: float, viscous: float, v_eps: float) -> float:
    """The bearing's torque over a step, taken at the velocity w1 the step ends with (backward
    Euler): w1 = v - hj F(w1), ``v`` the velocity the step would end with without the bearing,
    ``hj`` = h / J of the dof it acts on.

    With the exact sign (v_eps = 0) the bearing holds the dof at rest while |v| <= hj F_c (and
    applies v / hj, what stops it), else slides on: closed form. With a regularised sign the
    root of the increasing w1 + hj F(w1) - v is bracketed by 0 and v / (1 + hj d_f): Newton
    within the bracket (``roots``). Either way the solution exists, is unique and never
    reverses the motion, at any step and any F_c / J.
    """
    if hj <= 0.0:
        return 0.0
    if v_eps <= 0.0:
        if abs(v) <= hj * fc:
            return v / hj
        sg = 1.0 if v > 0.0 else -1.0
        return fc * sg + viscous * (v - hj * fc * sg) / (1.0 + hj * viscous)
    lo = 0.0
    hi = v / (1.0 + hj * viscous)
    if hi < lo:
        lo, hi = hi, lo
    w = 0.5 * (lo + hi)
    for _ in range(ITERATIONS):
        sg = smooth_sign(w, v_eps)
        g = w + hj * (fc * sg + viscous * w) - v
        w, lo, hi, done = newton_in_bracket(w, g, 1.0 + hj * (fc * (1.0 - sg * sg) / v_eps + viscous), lo, hi)
        if done:
            break
    return fc * smooth_sign(w, v_eps) + viscous * w


@dataclass(frozen=True)
class LoadFriction:
    """Output bearing friction, link side: N·m and N·m·s/rad."""

    fc: float = 0.5        # [N·m]: cross-roller output bearing, catalogue order for size 20
    viscous: float = 0.05  # d_f [N·m·s/rad]
    # Sign regularisation [rad/s]; 0 (default): the exact sign, a bearing that sticks. Any value
    # is stable at any step (``bearing_step``).
    v_eps: float = 0.0

    def __post_init__(self) -> None:
        check("fc", self.fc, 0.0)
        check("viscous", self.viscous, 0.0)
        check("v_eps", self.v_eps, 0.0)

    def __call__(self, w: float) -> float:
        return bearing_friction(w, self.fc, self.viscous, self.v_eps)


TERM = Term(section="load_friction", kinds={"bearing": LoadFriction}, site="link",
            doc="output bearing friction, Fc sgn(theta') + d_f theta'")
