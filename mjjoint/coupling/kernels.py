"""The joint's per-step physics on a parameter block and a state slice (pure, numba).

``joint_forces`` is what the plugin's compute adds to qfrc_passive (``joint_evaluate``: the
rotor's velocity-dependent torques linearly implicit, the transmission's stiffness limited);
``joint_advance`` is the step's update of the internal states, which compute applies first,
once per step (``joint_catch_up``, which also infers the torques the plugin does not see from
the step just taken). All take plain arrays, so the offline tools (traces, energy, tests)
evaluate the very functions the plugin runs. docs/design.md, "Integration", says what each
scheme converges to.
"""
from __future__ import annotations

import numpy as np
from numba import literal_unroll

from ..physics.boucwen import boucwen_step
from ..physics.jit import kernel
from ..physics.stribeck import static_friction, static_friction_slope, static_friction_step
from ..physics.transmission import engaged, transmission_stiffness, transmission_torque
from ..joint import STABILITY_BUDGET
from ..physics.twosep import presliding_unspent, reverses, twosep_step, twosep_step_from
from ..physics.load import bearing_friction, bearing_step
from .layout import (ANY_SITE, AT, FO, FOL, FOL2, FOT, FP, FPL, FRICTION, FRICTION_2SEP, FRICTION_STATIC, HYSTERESIS, LOAD,
                     OMEGA, QR, SITE_TERMS, ADVANCE_TERMS, SUB, TP, TRANSMISSION, WP, WPL, WSIGN, X, Z1, Z2)

F, T, H, L = FRICTION, TRANSMISSION, HYSTERESIS, LOAD

# A 2SEP step with an event (``twosep_event``) is taken in this many substeps: a tenth of the
# shipped step resolves the pre-sliding spring's ringing on the rotor (omega h = 0.9 at 0.5 ms).
SUBSTEPS = 10
# Below this many Stribeck velocities a step may hold a stop or a breakaway: there the lag's
# decay and the pre-sliding spring act within a step (10 Vs = 5 rad/s for the defaults).
EVENT_SPEED = 10.0


@kernel
def transmitted(blk, st, q, wq, theta, wtheta):
    """Transmission torque T (Eq. 18) from motor and link positions and velocities."""
    n = blk[T.gear_ratio]
    return transmission_torque(q / n - theta, wq / n - wtheta, st[X], blk[H.mu],
                               blk[T.k1], blk[T.k2], blk[T.k3], blk[T.damping], blk[T.backlash])


# Largest k h^2 / J an explicit spring is given: the stability check's budget (omega h = sqrt(3)).
STABLE_KR = 2.0 * STABILITY_BUDGET


@kernel
def rate_step(n, h, hj, hjl):
    """h^2 / J_rel of the deflection rate q'/N - theta': motor (through the gear) and link in
    series, from their h/J."""
    return h * (hj / (n * n) + hjl)


@kernel
def stiffness_limit(blk, st, t, de, in_gap, wq, wtheta, h, hj, hjl):
    """Torque that keeps the transmission spring stable at the step beyond its rated deflection.

    An explicit spring of tangent stiffness k between inertias with h^2 / J_rel = r diverges
    once k r > 4 (a hardening gear driven past its rated deflection). The stiffness above
    k_lim = ``STABLE_KR`` / r is taken position-implicitly: (k - k_lim) h times the deflection
    rate the step ends with, under the spring's torque ``t`` and the other torques on the
    deflection that the last step implies (``st[FOT]``; unknown: those balancing ``t``). Stable
    for any k, zero below the limit (ordinary runs are untouched), and zero as h -> 0, where
    k_lim grows as 1/h^2. ``de``: the engaged deflection; ``in_gap``: the teeth are apart.
    """
    if st[FOT] != st[FOT]:
        st[FOT] = t
    n = blk[T.gear_ratio]
    r = rate_step(n, h, hj, hjl)
    if r <= 0.0 or in_gap:
        return 0.0
    a = blk[H.a] if blk[H.kind] != 0.0 else 1.0
    excess = transmission_stiffness(de, st[X], blk[H.mu], blk[T.k1], blk[T.k2], blk[T.k3], a) - STABLE_KR / r
    if excess <= 0.0:
        return 0.0
    # J_rel d(rate)/dt = other - T, and h / J_rel = r / h
    return excess * h * ((wq / n - wtheta) + r / h * (st[FOT] - t)) / (1.0 + excess * r)


@kernel
def implicit_dof(f, g, other, hj):
    """Velocity change over a step of one dof under the joint's force f + g dw, g = df/dw <= 0.

    Semi-implicit Euler gives dw = hj (other + f + g dw) with the slope taken at the step's end
    (backward Euler in the dof's own velocity), so a damper of any slope neither reverses nor
    amplifies the motion, and a stiff one still balances the other forces (a friction that holds
    the rotor in slow sliding against the drive). ``other``: the rest of the dof's forces, as the
    last step implies them. ``hj`` = h/J, J the dof's apparent inertia.
    """
    return hj * (other + f) / (1.0 - g * hj)


@kernel
def known_other(st, slot, f):
    """The other torques on a dof, ``st[slot]`` (``FO``: the motor's, ``FOL``: the link's);
    where unknown (NaN: fresh states), those that balance the joint's torque f on it (without
    the 2SEP lag, without the bearing), recorded in their place: the dof then keeps its velocity
    but for those, and a static map acts as written."""
    if st[slot] != st[slot]:
        st[slot] = -f
    return st[slot]


@kernel
def bearing(blk, st, fl, wtheta, hjl):
    """The bearing friction's torque against the link over the step (``load.bearing_step``),
    with the link dof's other torques as the last step implies them (``known_other``). Without
    a link dof, the map at the link's velocity."""
    fc, visc, v_eps = blk[L.fc], blk[L.viscous], blk[L.v_eps]
    if hjl <= 0.0:
        return bearing_friction(wtheta, fc, visc, v_eps)
    other = 2.0 * st[FOL] - st[FOL2]
    return bearing_step(wtheta + hjl * (other + fl), hjl, fc, visc, v_eps)


@kernel
def site_torques(blk, st, q, wq, theta, wtheta):
    """Sum of the additive terms' generalised forces (motor, link), in declaration order; a term
    whose kind slot is 0 is absent."""
    fm = 0.0
    fl = 0.0
    for term in literal_unroll(SITE_TERMS):
        if blk[term[1]] != 0.0:
            a, b = term[0](blk, term[1], st, term[2], q, wq, theta, wtheta)
            fm += a
            fl += b
    return fm, fl


if ADVANCE_TERMS:  # numba cannot unroll an empty tuple
    @kernel
    def advance_terms(blk, st, q, wq, theta, wtheta, h):
        """Step the states of the additive terms that have any, in declaration order."""
        for term in literal_unroll(ADVANCE_TERMS):
            if blk[term[1]] != 0.0:
                term[0](blk, term[1], st, term[2], q, wq, theta, wtheta, h)
else:
    @kernel
    def advance_terms(blk, st, q, wq, theta, wtheta, h):
        """No additive term has states."""
        return


@kernel
def joint_evaluate(blk, st, q, wq, theta, wtheta, h, hj, hjl):
    """One evaluation of the joint at (q, wq, theta, wtheta) with states ``st``.

    Returns (fm, fl, T, F, F_L): the generalised forces on the motor and link dofs, the
    transmission torque as applied, the motor friction as applied, and the torque the bearing
    friction and the additive link-site terms apply against the link. The motor's
    velocity-dependent torques (friction, the 2SEP lag damper, transmission damping) are taken
    linearly implicitly against the motor dof's inertia, ``hj`` = h/J (``rotor``), or, for the
    static map's exact sign, at the velocity the step ends with (``exact_static_rotor``); the
    transmission spring is explicit up to its stability limit (``stiffness_limit``, ``hjl``: the
    link dof's h/J); the bearing friction at the link velocity the step ends with (``bearing``);
    friction levels and the rest of the link side are explicit.
    """
    n = blk[T.gear_ratio]
    t, in_gap = transmission(blk, st, q, wq, theta, wtheta, h, hj, hjl)
    d_eng = 0.0 if in_gap else blk[T.damping]
    # Motor: -T/N - F + ripple.
    kind = blk[F.kind]
    sm, sl = site_torques(blk, st, q, wq, theta, wtheta) if blk[ANY_SITE] != 0.0 else (0.0, 0.0)
    dl = load_level(blk, t)  # taken explicitly
    if kind == FRICTION_STATIC and blk[F.v_eps] <= 0.0 and hj > 0.0:
        fm, fric = exact_static_rotor(blk, st, -t / n + sm, -d_eng / (n * n), wq, hj, dl)
    else:
        fm, fric = rotor(blk, st, kind, -t / n + sm, -d_eng / (n * n), wq, h, hj, dl)
    # Link: T + the link-site terms, explicit (their velocity slopes are mild at the rated step),
    # less the bearing, which sticks: taken at the step's end.
    fl = t + sl
    known_other(st, FOL, fl)
    if st[FOL2] != st[FOL2]:
        st[FOL2] = st[FOL]
    fb = bearing(blk, st, fl, wtheta, hjl) if blk[L.kind] != 0.0 else 0.0
    return fm, fl - fb, t, fric, fb - sl


@kernel
def transmission(blk, st, q, wq, theta, wtheta, h, hj, hjl):
    """(T as ``joint_evaluate`` applies it, whether the teeth are apart): the spring (Eq. 18),
    its stiffness beyond the step's limit taken implicitly (``stiffness_limit``)."""
    t = transmitted(blk, st, q, wq, theta, wtheta)
    de = engaged(q / blk[T.gear_ratio] - theta, blk[T.backlash])
    in_gap = de == 0.0 and blk[T.backlash] > 0.0  # no torque passes, none of it damped
    return t + stiffness_limit(blk, st, t, de, in_gap, wq, wtheta, h, hj, hjl), in_gap


@kernel
def exact_static_rotor(blk, st, fx, gd, wq, hj, dl):
    """(torque on the motor dof, friction) with the static map's exact sign (v_eps = 0), taken
    at the velocity the step ends with together with the rotor's linear slope ``gd`` (the
    engaged teeth's damping): (1 - gd hj) w1 + hj F(w1) = (1 - gd hj) wq + hj (other + fx)
    (``stribeck.static_friction_step``); ``fx``: the joint's explicit torque on the rotor,
    ``dl``: what the load adds to both friction levels."""
    fc, fs, vs, shape = blk[F.fc] + dl, blk[F.fs] + dl, blk[F.vs], blk[F.shape]
    sigma, asym, sigma_asym = blk[F.sigma], blk[F.asym], blk[F.sigma_asym]
    om = known_other(st, FO, fx - static_friction(wq, fc, fs, vs, shape, sigma, asym, 0.0, sigma_asym))
    k = 1.0 - gd * hj
    a = k * wq + hj * (om + fx)
    w1, fric = static_friction_step(a, k, hj, fc, fs, vs, shape, sigma, asym, sigma_asym)
    return fx + gd * (w1 - wq) - fric, fric


@kernel
def rotor(blk, st, kind, fx, gd, wq, h, hj, dl):
    """(torque on the motor dof, friction) with 2SEP or the regularised static map: the
    velocity slopes linearly implicit (``implicit_dof``); ``fx``: the joint's explicit torque on
    the rotor, ``gd`` its linear slope. 2SEP: ``twosep_velocity``, or over a step with an event
    (``twosep_event``) the rotor substepped (``twosep_substeps``); either way the torque applied
    is what lands MuJoCo's update on the end velocity found. ``dl``: what the load adds to the
    friction levels."""
    if kind == FRICTION_2SEP:
        if blk[F.load_gain] != 0.0 and st[TP] == st[TP]:  # states advanced at the last evaluation's level
            presliding_level(blk, st, load_level(blk, st[TP]), dl)
        om = known_other(st, FO, fx - st[Z1])
        w1, fric = twosep_velocity(blk, st[Z1], st[Z2], fx, gd, om, wq, hj)
        st[SUB] = 0.0
        if hj > 0.0 and twosep_event(blk, st[WSIGN], wq, w1):
            w1, z1, z2, omega, qr, ws = twosep_substeps(blk, st[Z1], st[Z2], st[OMEGA], st[QR], st[WSIGN], fx, gd,
                                                        om, wq, h, hj, SUBSTEPS, dl)
            st[SUB] = 1.0  # the advance takes the states where the substeps ended
            st[SUB + 1] = z1
            st[SUB + 2] = z2
            st[SUB + 3] = omega
            st[SUB + 4] = qr
            st[SUB + 5] = ws
            # the mean friction over the step: J (w1 - wq) / h = other + fx + gd (w1 - wq) - fric
            fric = om + fx + gd * (w1 - wq) - (w1 - wq) / hj
        return fx + gd * (w1 - wq) - fric, fric
    f0 = 0.0
    s0 = 0.0
    if kind == FRICTION_STATIC:
        fc, fs = blk[F.fc] + dl, blk[F.fs] + dl
        f0 = static_friction(wq, fc, fs, blk[F.vs], blk[F.shape], blk[F.sigma], blk[F.asym], blk[F.v_eps],
                             blk[F.sigma_asym])
        if blk[F.v_eps] > 0.0:  # (the exact sign without a motor dof: the map at wq)
            s0 = max(0.0, static_friction_slope(wq, fc, fs, blk[F.vs], blk[F.shape], blk[F.sigma],
                                                blk[F.asym], blk[F.v_eps], blk[F.sigma_asym]))
    fm = fx - f0
    gm = gd - s0
    om = known_other(st, FO, fm)
    dwm = implicit_dof(fm, gm, om, hj)
    return fm + gm * dwm, f0 + s0 * dwm


@kernel
def load_level(blk, t):
    """What the transmission torque ``t`` adds to both friction levels (load-dependent friction):
    load_gain |T| / N."""
    return blk[F.load_gain] * abs(t) / blk[T.gear_ratio]


@kernel
def presliding_level(blk, st, dl_from, dl_to):
    """2SEP's pre-sliding in ``st`` carried from levels raised by ``dl_from`` to ``dl_to``
    (load-dependent friction): z1 and Omega scaled by the ratio of the Coulomb levels in the
    motion's direction, so the whole pre-sliding curve follows the load (a contact pressed
    harder holds more at the same displacement) and a saturated z1 sits at the new level."""
    base = blk[F.fc] + blk[F.asym] * st[WSIGN]
    r = (base + dl_to) / (base + dl_from)
    st[Z1] *= r
    st[OMEGA] *= r


@kernel
def twosep_velocity(blk, z1, z2, fx, gd, om, wq, hj):
    """(end velocity w1, friction) of the rotor over a step or a substep with 2SEP: z1 from its
    start, the lag a one-sided damper ``c`` = B|z2| decided on the velocity it would reach without
    it, linearly implicit with the rotor's other slopes. A step that this w1 shows to reverse the
    motion holds an event and is substepped (``twosep_event``); a substep that reverses it takes
    z1 explicitly too, so the substeps' answer has no jump where a reversal moves from one
    substep to the next."""
    fm = fx - z1
    w1 = wq + implicit_dof(fm, gd, om, hj)
    c = blk[F.b] * abs(z2) if z2 * w1 > 0.0 else 0.0
    if c != 0.0:
        # w1 = wq + hj (other + fm - c w1 + gd (w1 - wq)), solved as one quotient: the damper's
        # force taken apart from the others' sum keeps a rotor the lag brings to rest from
        # crossing zero on the sum's rounding.
        kd = 1.0 - gd * hj
        w1 = (kd * wq + hj * (om + fm)) / (kd + c * hj)
    return w1, z1 + c * w1


@kernel
def twosep_event(blk, wsign, wq, w1):
    """Whether a step from ``wq`` that would end at ``w1`` holds an event the step cannot place:
    a reversal of the motion, or the rotor below ``EVENT_SPEED`` Stribeck velocities at either
    end (sticking, breaking away: the lag and the pre-sliding spring stiff against its inertia)."""
    if reverses(w1, wsign):
        return True
    slow = EVENT_SPEED * blk[F.vs]
    return abs(wq) < slow or abs(w1) < slow


@kernel
def twosep_substeps(blk, z1, z2, omega, qr, wsign, fx, gd, om, wq, h, hj, n, dl):
    """The rotor and its 2SEP states over a step from ``wq`` in ``n`` substeps, each as a step of
    its own (``twosep_velocity``, ``twosep.twosep_step``), the torques on the rotor but the
    friction frozen at the step's: the other torques ``om`` and the joint's ``fx`` + ``gd`` (w - wq),
    ``gd`` <= 0 its linear slope (kept apart as in the step's own solve, so that a rotor held at
    rest by a balance to the last bit stays there). Returns (w1, z1, z2, omega, qr, wsign)."""
    hs = h / n
    hjs = hj / n
    w = wq
    unspent = presliding_unspent(qr, blk[F.k])  # carried from substep to substep
    for _ in range(n):
        w1, _ = twosep_velocity(blk, z1, z2, fx + gd * (w - wq), gd, om, w, hjs)
        z1, z2, omega, qr, wsign, unspent = twosep_step_from(z1, z2, omega, qr, wsign, w1, hs, blk[F.fc] + dl,
                                                             blk[F.fs] + dl, blk[F.vs], blk[F.shape], blk[F.sigma],
                                                             blk[F.k], blk[F.b], blk[F.asym], blk[F.sigma_asym],
                                                             unspent)
        w = w1
    return w, z1, z2, omega, qr, wsign


@kernel
def joint_forces(blk, st, q, wq, theta, wtheta, h, hj, hjl):
    """Generalised forces (motor, link) of the joint physics, -T/N - F + ripple and T - F_L, as
    ``joint_evaluate`` applies them; records the velocities, the motor torque and the
    transmission torque in ``st`` for the next step's estimates of the other torques on the
    motor and on the deflection (``joint_catch_up``)."""
    fm, fl, t, _, _ = joint_evaluate(blk, st, q, wq, theta, wtheta, h, hj, hjl)
    st[WP] = wq
    st[FP] = fm
    st[WPL] = wtheta
    st[TP] = t
    st[FPL] = fl
    return fm, fl


@kernel
def joint_advance(blk, st, q, wq, theta, wtheta, h):
    """Advance the internal states over a step that ended at (q, theta) with velocities (wq, wtheta).

    Called after MuJoCo's semi-implicit Euler update, where q_new = q_old + wq h exactly for
    hinge and slide joints, so the step's increments are the new velocities times h.
    """
    if blk[F.kind] == FRICTION_2SEP:
        if st[SUB] == 1.0:  # substepped over the step (``rotor``): the states where that ended
            st[Z1] = st[SUB + 1]
            st[Z2] = st[SUB + 2]
            st[OMEGA] = st[SUB + 3]
            st[QR] = st[SUB + 4]
            st[WSIGN] = st[SUB + 5]
            st[SUB] = 0.0
        else:  # at the levels the step's evaluation applied (its transmission torque)
            friction_step(blk, st, wq, h, load_level(blk, st[TP]))
    if blk[H.kind] != 0.0:
        n = blk[T.gear_ratio]
        delta = q / n - theta
        st[X] = hysteresis_step(blk, st[X], delta - (wq / n - wtheta) * h, delta)
    if blk[ANY_SITE] != 0.0:
        advance_terms(blk, st, q, wq, theta, wtheta, h)


@kernel
def joint_catch_up(blk, st, q, wq, theta, wtheta, t, h, hj, hjl):
    """Bring the states, last brought to ``st[AT]``, to time ``t``: the pending step's
    ``joint_advance`` if a step has passed since, none at the same time (a repeated
    mj_forward), none for fresh states (``st[AT]`` NaN: a reset, states set by hand).

    A step also tells the other torques on the motor dof, its velocity change since the last
    evaluation less what the joint applied then (J dw / h - f), and likewise those on the link
    dof and on the deflection (J_rel d rate / h + T). Fresh states leave them unknown, and
    the friction levels their states were advanced at with them (``presliding_level``).

    The plugin does this at the start of compute rather than in a MuJoCo advance callback:
    same states, same forces, one callback a step instead of two (docs/design.md). So after
    mj_step, ``plugin_state`` still holds the states of the step's start; ``settled_states``
    gives them at the step's end.
    """
    at = st[AT]
    if at == at and at != t:
        joint_advance(blk, st, q, wq, theta, wtheta, h)
        dwq = wq - st[WP]
        st[FO] = dwq / hj - st[FP] if hj > 0.0 else 0.0
        n = blk[T.gear_ratio]
        r = rate_step(n, h, hj, hjl)
        st[FOT] = (dwq / n - (wtheta - st[WPL])) * h / r + st[TP] if r > 0.0 else 0.0
        st[FOL2] = st[FOL]
        st[FOL] = (wtheta - st[WPL]) / hjl - st[FPL] if hjl > 0.0 else 0.0
    elif at != at:
        st[FO] = np.nan
        st[FOT] = np.nan
        st[FOL] = np.nan
        st[FOL2] = np.nan
        st[TP] = np.nan  # fresh states are taken at the levels of their first evaluation
    st[AT] = t


@kernel
def settled_states(blk, states, t, q, wq, theta, wtheta, h, hj, hjl):
    """Copies of plugin-state rows (n, NSTATE) recorded at times ``t``, each caught up to its own
    time (``joint_catch_up``): the internal states at the recorded instants."""
    out = states.copy()
    for i in range(out.shape[0]):
        joint_catch_up(blk, out[i], q[i], wq[i], theta[i], wtheta[i], t[i], h, hj, hjl)
    return out


@kernel
def settled_transmission(blk, states, t, q, wq, theta, wtheta, h, hj, hjl):
    """``joint_traces``' transmission torque from ``settled_states``, row by row (neither a copy
    of all rows nor the rotor and the bearing evaluated): ``states`` may be a strided view."""
    tau = np.empty(q.shape[0])
    st = np.empty(states.shape[1])
    for i in range(q.shape[0]):
        st[:] = states[i]
        joint_catch_up(blk, st, q[i], wq[i], theta[i], wtheta[i], t[i], h, hj, hjl)
        tau[i], _ = transmission(blk, st, q[i], wq[i], theta[i], wtheta[i], h, hj, hjl)
    return tau


@kernel
def friction_step(blk, st, w, h, dl):
    """Advance the 2SEP states in ``st`` over a step of length h ending at motor velocity w, its
    levels raised by ``dl`` (load-dependent friction)."""
    z1, z2, om, qr, ws = twosep_step(st[Z1], st[Z2], st[OMEGA], st[QR], st[WSIGN], w, h,
                                     blk[F.fc] + dl, blk[F.fs] + dl, blk[F.vs], blk[F.shape], blk[F.sigma],
                                     blk[F.k], blk[F.b], blk[F.asym], blk[F.sigma_asym])
    st[Z1] = z1
    st[Z2] = z2
    st[OMEGA] = om
    st[QR] = qr
    st[WSIGN] = ws


@kernel
def friction_history(blk, w, torque, h, st0):
    """2SEP states after each sample of a motor velocity sequence (sample period h), from ``st0``,
    under the gear torque ``torque`` (per sample; it sets load-dependent levels).

    The states are the friction's memory of the motion (reversal point, pre-sliding, lag): a
    measured velocity gives them along a recording, as the plugin's advance would have.
    """
    out = np.empty((w.shape[0], st0.shape[0]))
    st = st0.copy()
    level = 0.0
    for i in range(w.shape[0]):
        last, level = level, load_level(blk, torque[i])
        if i > 0 and blk[F.load_gain] != 0.0:
            presliding_level(blk, st, last, level)
        friction_step(blk, st, w[i], h, level)
        out[i] = st
    return out


@kernel
def hysteresis_step(blk, x, delta_from, delta_to):
    """Bouc-Wen x driven by the deflection moving from ``delta_from`` to ``delta_to`` (past the play)."""
    de = engaged(delta_to, blk[T.backlash]) - engaged(delta_from, blk[T.backlash])
    return boucwen_step(x, de, blk[H.a], blk[H.beta], blk[H.gamma], blk[H.n])


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
def joint_traces(blk, states, q, wq, theta, wtheta, h, hj, hjl):
    """Transmission torque, motor friction and load friction along a trajectory, as
    ``joint_evaluate`` gives them from settled states."""
    n = q.shape[0]
    tau = np.empty(n)
    fric = np.empty(n)
    load = np.empty(n)
    for i in range(n):
        _, _, tau[i], fric[i], load[i] = joint_evaluate(blk, states[i], q[i], wq[i], theta[i], wtheta[i], h, hj, hjl)
    return tau, fric, load
