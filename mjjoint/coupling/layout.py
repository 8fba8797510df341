"""Memory layouts shared by the Python side and the numba callbacks.

``BLOCK``: the per-instance float64 parameter block (a ``registry`` row, which
``d->plugin_data[instance]`` caches), built once per model from the instance's MJCF config.
``STATE``: the instance's slice of ``d->plugin_state``, i.e. the internal states MuJoCo saves,
restores, resets and rolls out.
"""
from __future__ import annotations

import numpy as np

from ..joint import JointParams
from ..physics.stribeck import StaticFriction
from ..physics.twosep import TwoSEP

# Parameter block indices.
(MQ, MD, LQ, LD,
 FKIND, FC, FS, VS, SHAPE, SIGMA, K, B, ASYM, VEPS,
 GEAR, K1, K2, K3, DAMP, BACKLASH,
 HYST, MU, BW_A, BW_BETA, BW_GAMMA, BW_N,
 LOAD, L_FC, L_VISC, L_VEPS,
 RIPPLE, R_AMP, R_K, R_PHASE,
 VASYM) = range(35)
BLOCK_LEN = 35
FRICTION_NONE, FRICTION_STATIC, FRICTION_2SEP = 0.0, 1.0, 2.0

# Plugin state indices: the 2SEP states (twosep.Z1 ... WSIGN), the Bouc-Wen x, then the time
# the states hold at (NaN: at whatever time they are next evaluated; kernels.joint_catch_up),
# then the integrator's memory: the motor's velocity and the joint's torque on it at the last
# evaluation and the other torques on it that the step since implies (kernels.implicit_dof), the
# link's velocity and the transmission torque at the last evaluation and the other torques on the
# deflection (kernels.stiffness_limit). NaN: unknown, after a reset or for states set by hand.
Z1, Z2, OMEGA, QR, WSIGN, X, AT, WP, FP, FO, WPL, TP, FOT = range(13)
NSTATE = 13
STATE_NAMES = ("z1", "z2", "omega", "q_r", "w_sign", "x")  # the physical ones, before AT


def pack(params: JointParams, motor_qpos: int, motor_dof: int, link_qpos: int, link_dof: int) -> np.ndarray:
    """The parameter block of one plugin instance."""
    b = np.zeros(BLOCK_LEN)
    b[[MQ, MD, LQ, LD]] = motor_qpos, motor_dof, link_qpos, link_dof
    f = params.friction
    if f is not None:  # the static map's fields, which 2SEP shares
        b[[FC, FS, VS, SHAPE, SIGMA, ASYM, VASYM]] = f.fc, f.fs, f.vs, f.shape, f.sigma, f.asym, f.sigma_asym
    if isinstance(f, TwoSEP):
        b[[FKIND, K, B, VEPS]] = FRICTION_2SEP, f.k, f.b, 1.0
    elif isinstance(f, StaticFriction):
        b[[FKIND, VEPS]] = FRICTION_STATIC, f.v_eps
    t = params.transmission
    b[GEAR] = params.gear_ratio  # a direct drive: N = 1 and no stiffness, so T = 0
    b[MU] = 1.0
    if t is not None:
        b[[K1, K2, K3, DAMP, BACKLASH]] = t.k1, t.k2, t.k3, t.damping, t.backlash
    if t is not None and t.hysteresis is not None:
        h = t.hysteresis
        b[[HYST, MU, BW_A, BW_BETA, BW_GAMMA, BW_N]] = 1.0, h.mu, h.a, h.beta, h.gamma, h.n
    if params.load_friction is not None:
        lf = params.load_friction
        b[[LOAD, L_FC, L_VISC, L_VEPS]] = 1.0, lf.fc, lf.viscous, lf.v_eps
    if params.ripple is not None:
        r = params.ripple
        b[[RIPPLE, R_AMP, R_K, R_PHASE]] = 1.0, r.amplitude, r.harmonic, r.phase
    return b
