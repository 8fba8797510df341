"""Load side: bearing friction F_c sgn(theta') + d_f theta' (Sec. 2.3).

Gravity G = l g sin(theta) (Eq. 9) and link flexibility are not written here: they come from
the MJCF bodies (link mass, lever, flexible segments) through MuJoCo's multibody dynamics.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..params import check
from .jit import kernel
from .stribeck import smooth_sign
from .term import Term


@kernel
def bearing_friction(w: float, fc: float, viscous: float, v_eps: float) -> float:
    """F_c tanh(w / v_eps) + d_f w: the smoothed sign keeps the ODE Lipschitz at w = 0."""
    return fc * smooth_sign(w, v_eps) + viscous * w


@dataclass(frozen=True)
class LoadFriction:
    """Output bearing friction, link side: N·m and N·m·s/rad."""

    fc: float = 0.5        # [N·m]: cross-roller output bearing, catalogue order for size 20
    viscous: float = 0.05  # d_f [N·m·s/rad]
    # Sign regularisation [rad/s]: explicit stability needs fc h/(v_eps J) < 2 (1.5 with margin)
    # on the apparent inertia behind the gear, the hub alone for a flexible rod (2e-3 kg m^2,
    # 1.6e-3 for an elbow on a recoiling upper arm); 0.15 rad/s gives 1.04 there at fc = 0.5 N m.
    v_eps: float = 0.15

    def __post_init__(self) -> None:
        check("fc", self.fc, 0.0)
        check("viscous", self.viscous, 0.0)
        check("v_eps", self.v_eps, 0.0, lo_open=True)

    def __call__(self, w: float) -> float:
        return bearing_friction(w, self.fc, self.viscous, self.v_eps)


@kernel
def load_torque(blk, o, st, s, q, wq, theta, wtheta):
    """The term's generalised forces (motor, link): the bearing friction against the link."""
    return 0.0, -bearing_friction(wtheta, blk[o + P.fc], blk[o + P.viscous], blk[o + P.v_eps])


TERM = Term(section="load_friction", kinds={"bearing": LoadFriction}, site="link",
            doc="output bearing friction, Fc sgn(theta') + d_f theta'", torque=load_torque,
            stability=lambda lf, motor_inertia, link_inertia: (
                {}, {"load_friction.v_eps (Coulomb slope)": (lf.fc / lf.v_eps + lf.viscous) / link_inertia}))
P = TERM.offsets
