"""The motor friction term: the 2SEP model (``twosep``) or a static map (``stribeck``).

Both kinds share the static map's fields, so a kind change keeps the levels. The joint's scheme
integrates this term together with the rotor (``coupling.kernels``); its states are 2SEP's.
"""
from __future__ import annotations

import numpy as np

from .stribeck import StaticFriction, steady_state
from .term import Term
from .twosep import TwoSEP

# 2SEP's states: pre-sliding force z1 (12), lag z2 (14), stiffness capacity Omega (13), the
# displacement since the last reversal q_r, and the sign of the motion since then.
STATES = ("z1", "z2", "omega", "q_r", "w_sign")


def _stability(f, motor_inertia: float, link_inertia: float):
    """2SEP's pre-sliding spring, or the regularised static map's slope at w = 0, on the rotor."""
    if isinstance(f, TwoSEP):
        return {"friction.k (pre-sliding stiffness)": 2 * (f.fs + abs(f.asym)) * f.k / motor_inertia}, {}
    if f.v_eps == 0:  # the exact sign, taken at the step's end: stable at any step
        return {}, {}
    return {}, {"friction.v_eps (Coulomb slope)": (max(f.fc, f.fs) + abs(f.asym)) / (f.v_eps * motor_inertia)
                + f.sigma * (1 + abs(f.sigma_asym)) / motor_inertia}


def _steady(f, motion: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """2SEP on its steady sliding branch at the motor velocities: pre-sliding saturated far from
    the last reversal, the lag at S(w). A static map has no states."""
    if not isinstance(f, TwoSEP):
        return {}
    w = motion["w"]
    sg = np.sign(w)
    z1 = sg * (f.fc + f.asym * sg)
    s = np.array([steady_state(v, f.fc, f.fs, f.vs, f.shape, f.sigma, f.asym, f.sigma_asym) for v in w])
    bw = f.b * np.abs(w)
    z2 = np.where(bw > 0, (s - z1) / np.where(bw > 0, bw, 1.0), 0.0)
    return {"w_sign": sg, "z1": z1, "q_r": np.full(len(w), 1e6), "z2": z2}


TERM = Term(
    section="friction", kinds={"2sep": TwoSEP, "static": StaticFriction}, site="motor",
    doc="motor friction: 2SEP dynamic friction (Eqs. 11-15) or a static Stribeck map",
    states=STATES, stability=_stability, steady=_steady)
