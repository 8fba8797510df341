"""The joint's per-step physics on a parameter block and a state slice (pure, numba).

``joint_forces`` is what the plugin's compute adds to qfrc_passive; ``joint_advance`` is the
step's update of the internal states, which compute applies first, once per step
(``joint_catch_up``). All take plain arrays, so the offline tools (traces, energy, tests)
evaluate the very functions the plugin runs.
"""
from __future__ import annotations

import numpy as np

from ..physics.boucwen import boucwen_step
from ..physics.jit import kernel
from ..physics.load import bearing_friction
from ..physics.ripple import ripple_torque
from ..physics.stribeck import static_friction
from ..physics.transmission import engaged, transmission_torque
from ..physics.twosep import twosep_force_implicit, twosep_step
from .layout import (ASYM, AT, B, BACKLASH, BW_A, BW_BETA, BW_GAMMA, BW_N, DAMP, FC, FKIND,
                     FRICTION_2SEP, FRICTION_STATIC, FS, GEAR, HYST, K, K1, K2, K3, L_FC,
                     L_VEPS, L_VISC, LOAD, MU, OMEGA, QR, R_AMP, R_K, R_PHASE, RIPPLE,
                     SHAPE, SIGMA, VASYM, VEPS, VS, WSIGN, X, Z1, Z2)


@kernel
def motor_friction(blk, st, w, hj):
    """Friction torque opposing the motor (2SEP, static map or none).

    ``hj`` = h / J, the step over the motor dof's apparent inertia: 2SEP's lag term is applied
    linearly implicitly against it (``twosep.twosep_force_implicit``).
    """
    kind = blk[FKIND]
    if kind == FRICTION_2SEP:
        return twosep_force_implicit(st[Z1], st[Z2], w, blk[B], hj)
    if kind == FRICTION_STATIC:
        return static_friction(w, blk[FC], blk[FS], blk[VS], blk[SHAPE], blk[SIGMA], blk[ASYM], blk[VEPS],
                               blk[VASYM])
    return 0.0


@kernel
def transmitted(blk, st, q, wq, theta, wtheta):
    """Transmission torque T (Eq. 18) from motor and link positions and velocities."""
    n = blk[GEAR]
    return transmission_torque(q / n - theta, wq / n - wtheta, st[X], blk[MU],
                               blk[K1], blk[K2], blk[K3], blk[DAMP], blk[BACKLASH])


@kernel
def joint_forces(blk, st, q, wq, theta, wtheta, hj):
    """Generalised forces (motor, link) of the joint physics: -T/N - F + ripple, T - F_L."""
    t = transmitted(blk, st, q, wq, theta, wtheta)
    fm = -t / blk[GEAR] - motor_friction(blk, st, wq, hj)
    if blk[RIPPLE] != 0.0:
        fm += ripple_torque(q, blk[R_AMP], blk[R_K], blk[R_PHASE])
    fl = t
    if blk[LOAD] != 0.0:
        fl -= bearing_friction(wtheta, blk[L_FC], blk[L_VISC], blk[L_VEPS])
    return fm, fl


@kernel
def joint_advance(blk, st, q, wq, theta, wtheta, h):
    """Advance the internal states over a step that ended at (q, theta) with velocities (wq, wtheta).

    Called after MuJoCo's semi-implicit Euler update, where q_new = q_old + wq h exactly for
    hinge and slide joints, so the step's increments are the new velocities times h.
    """
    if blk[FKIND] == FRICTION_2SEP:
        friction_step(blk, st, wq, h)
    if blk[HYST] != 0.0:
        n = blk[GEAR]
        delta = q / n - theta
        st[X] = hysteresis_step(blk, st[X], delta - (wq / n - wtheta) * h, delta)


@kernel
def joint_catch_up(blk, st, q, wq, theta, wtheta, t, h):
    """Bring the states, last brought to ``st[AT]``, to time ``t``: the pending step's
    ``joint_advance`` if a step has passed since, none at the same time (a repeated
    mj_forward), none for fresh states (``st[AT]`` NaN: a reset, states set by hand).

    The plugin does this at the start of compute rather than in a MuJoCo advance callback:
    same states, same forces, one callback a step instead of two (docs/design.md). So after
    mj_step, ``plugin_state`` still holds the states of the step's start; ``settled_states``
    gives them at the step's end.
    """
    at = st[AT]
    if at == at and at != t:
        joint_advance(blk, st, q, wq, theta, wtheta, h)
    st[AT] = t


@kernel
def settled_states(blk, states, t, q, wq, theta, wtheta, h):
    """Copies of plugin-state rows (n, NSTATE) recorded at times ``t``, each caught up to its own
    time (``joint_catch_up``): the internal states at the recorded instants."""
    out = states.copy()
    for i in range(out.shape[0]):
        joint_catch_up(blk, out[i], q[i], wq[i], theta[i], wtheta[i], t[i], h)
    return out


@kernel
def friction_step(blk, st, w, h):
    """Advance the 2SEP states in ``st`` over a step of length h ending at motor velocity w."""
    z1, z2, om, qr, ws = twosep_step(st[Z1], st[Z2], st[OMEGA], st[QR], st[WSIGN], w, h,
                                     blk[FC], blk[FS], blk[VS], blk[SHAPE], blk[SIGMA],
                                     blk[K], blk[B], blk[ASYM], blk[VASYM])
    st[Z1] = z1
    st[Z2] = z2
    st[OMEGA] = om
    st[QR] = qr
    st[WSIGN] = ws


@kernel
def friction_history(blk, w, h, st0):
    """2SEP states after each sample of a motor velocity sequence (sample period h), from ``st0``.

    The states are the friction's memory of the motion (reversal point, pre-sliding, lag): a
    measured velocity gives them along a recording, as the plugin's advance would have.
    """
    out = np.empty((w.shape[0], st0.shape[0]))
    st = st0.copy()
    for i in range(w.shape[0]):
        friction_step(blk, st, w[i], h)
        out[i] = st
    return out


@kernel
def hysteresis_step(blk, x, delta_from, delta_to):
    """Bouc-Wen x driven by the deflection moving from ``delta_from`` to ``delta_to`` (past the play)."""
    de = engaged(delta_to, blk[BACKLASH]) - engaged(delta_from, blk[BACKLASH])
    return boucwen_step(x, de, blk[BW_A], blk[BW_BETA], blk[BW_GAMMA], blk[BW_N])


@kernel
def hysteresis_history(blk, delta, x0):
    """Bouc-Wen x after each sample of a deflection sequence, starting from ``x0``.

    Bouc-Wen is rate independent: x at any instant follows from the deflection path alone, so
    a measured deflection gives the hysteresis state along a recording.
    """
    x = np.empty(delta.shape[0])
    xi = x0
    for i in range(delta.shape[0]):
        if i > 0:
            xi = hysteresis_step(blk, xi, delta[i - 1], delta[i])
        x[i] = xi
    return x


@kernel
def joint_traces(blk, states, q, wq, theta, wtheta, hj):
    """Transmission torque, motor friction and load friction along a trajectory (``hj``: as in
    ``motor_friction``)."""
    n = q.shape[0]
    tau = np.empty(n)
    fric = np.empty(n)
    load = np.empty(n)
    for i in range(n):
        st = states[i]
        tau[i] = transmitted(blk, st, q[i], wq[i], theta[i], wtheta[i])
        fric[i] = motor_friction(blk, st, wq[i], hj)
        load[i] = bearing_friction(wtheta[i], blk[L_FC], blk[L_VISC], blk[L_VEPS]) if blk[LOAD] != 0.0 else 0.0
    return tau, fric, load
