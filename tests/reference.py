"""Plain-Python reference implementations of every numba kernel, written from Ruderman (2012).

Each function is derived from the chapter's equation (cited in its docstring) and the
integration scheme the kernel's module documents, not from the kernel's code: the tests
compare the compiled kernels against these on random inputs. The composite ``joint_forces``
and ``joint_advance`` take a ``JointParams`` and a named state, so they also check the
parameter packing. Only ``math`` is used; no numba, no numpy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from mjjoint.coupling.kernels import EVENT_SPEED, SUBSTEPS
from mjjoint.joint import JointParams
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.physics.twosep import TwoSEP


def sgn(v: float) -> float:
    return float(v > 0.0) - float(v < 0.0)


# ---- Stribeck curve, Eq. 15 -------------------------------------------------------------
def stribeck_level(w, fc, fs, vs, shape):
    """|s(w)| = Fc + (Fs - Fc) exp(-|w/Vs|^delta), Eq. 15 without its sign."""
    return fc + (fs - fc) * math.exp(-(abs(w) / vs) ** shape)


def steady_state(w, fc, fs, vs, shape, sigma, asym, sigma_asym):
    """S(w) = s(w) + sigma w (Eqs. 14-15); asym raises both levels in the direction of motion,
    and the viscous force gains sigma_asym sigma |w| (slopes sigma (1 +- sigma_asym))."""
    d = sgn(w)
    return d * stribeck_level(w, fc + asym * d, fs + asym * d, vs, shape) + sigma * w + sigma_asym * sigma * abs(w)


def static_friction(w, fc, fs, vs, shape, sigma, asym, v_eps, sigma_asym):
    """S(w) with every sgn(w) replaced by tanh(w / v_eps) (|w| by w tanh(w / v_eps)); v_eps = 0:
    S(w) itself."""
    if v_eps == 0:
        return steady_state(w, fc, fs, vs, shape, sigma, asym, sigma_asym)
    d = math.tanh(w / v_eps)
    return d * stribeck_level(w, fc + asym * d, fs + asym * d, vs, shape) + sigma * w + sigma_asym * sigma * w * d


def static_friction_step(a, k, hj, fc, fs, vs, shape, sigma, asym, sigma_asym):
    """Backward Euler for the exact static map on a dof of h/J = hj with other slopes k:
    k w1 + hj S(w1) = a, S set-valued at rest. The root by
    bisection on the side of a (one root where the level does not dip: Fs <= Fc). Returns
    (w1, S)."""
    if hj <= 0:
        return a / k, 0.0
    if -hj * (fs - asym) <= a <= hj * (fs + asym):
        return 0.0, a / hj  # holds
    d = sgn(a)
    # the bracket's small end just off rest (S is set-valued at 0), below any root: tiny drives too
    lo, hi = sorted((d * min(1e-300, 1e-20 * abs(a / k)), a / k))
    for _ in range(300):
        mid = 0.5 * (lo + hi)
        if (k * mid + hj * steady_state(mid, fc, fs, vs, shape, sigma, asym, sigma_asym) - a) > 0:
            hi = mid
        else:
            lo = mid
    w1 = 0.5 * (lo + hi)
    return w1, steady_state(w1, fc, fs, vs, shape, sigma, asym, sigma_asym)


# ---- 2SEP, Eqs. 11-15 -------------------------------------------------------------------
def twosep_force(z1, z2, w, b):
    """F = A z1 + B |w| z2 with A = 1 (Eq. 11); the lag term only while it opposes the motion."""
    lag = b * abs(w) * z2
    return 1.0 * z1 + (lag if sgn(z2) == sgn(w) != 0 else 0.0)


def lag_target(w, fc, fs, vs, shape, sigma, asym, sigma_asym):
    """S(w) as Eq. 14 drives z2 with it: sgn(w) regularised, tanh over a tenth of Vs."""
    d = sgn(w)
    return (math.tanh(w / (0.1 * vs)) * stribeck_level(w, fc + asym * d, fs + asym * d, vs, shape)
            + sigma * (1 + sigma_asym * d) * w)


def _presliding_primitive(s, k):
    """A primitive of K exp(-K|s|) in s: Eq. 12 reads dz1 = |Omega| K exp(-K|q_r|) dq_r."""
    return sgn(s) * (1.0 - math.exp(-k * abs(s)))


def twosep_step(z1, z2, omega, qr, wsign, w, h, fc, fs, vs, shape, sigma, k, b, asym, sigma_asym):
    """One step of length h at constant velocity w: (z1, z2, Omega, q_r, sgn of last motion).

    A reversal (w of the opposite sign to the last motion, or the first motion) stores
    Omega = sgn(w) Fc - F (Eq. 13) with F = z1, the force at the instant w crosses zero,
    and restarts q_r.
    z1 follows Eq. 12 integrated exactly along q_r; z2 follows Eq. 14 by backward Euler, with
    F = z1 + B|w| z2 taken at the end of the step and |S| the magnitude of the Stribeck curve
    plus sigma|w| (the curve's value Fs at w = 0 keeps Eq. 14 finite there).
    """
    d = sgn(w)
    if d != 0 and d != wsign:
        omega = abs(d * (fc + asym * d) - z1)
        qr = 0.0
        wsign = d
    qr_end = qr + w * h
    z1 = z1 + abs(omega) * (_presliding_primitive(qr_end, k) - _presliding_primitive(qr, k))
    s_abs = stribeck_level(w, fc + asym * d, fs + asym * d, vs, shape) + sigma * (1 + sigma_asym * d) * abs(w)
    target = lag_target(w, fc, fs, vs, shape, sigma, asym, sigma_asym)
    # z2' = (target - z1)/|S| - (B|w|/|S|) z2 with w and z1 frozen: the exact exponential solution.
    lam = b * abs(w) / s_abs
    drive = (target - z1) / s_abs
    # (1 - e^{-lam h}) / lam, with its limit h where lam h is too small to carry digits
    z2 = z2 * math.exp(-lam * h) + (drive * -math.expm1(-lam * h) / lam if lam * h > 1e-12 else drive * h)
    return z1, z2, omega, qr_end, wsign


# ---- Hysteretic stiffness, Eqs. 16-17 ----------------------------------------------------
def _stiffness_polynomial(v, k1, k2, k3):
    """sum_i k_i sgn(v)|v|^i for i = 1, 2, 3."""
    return sum(ki * sgn(v) * abs(v) ** i for i, ki in ((1, k1), (2, k2), (3, k3)))


def spring_potential(v, k1, k2, k3):
    """Integral of the stiffness polynomial from 0 to v: k1 v^2/2 + k2 |v|^3/3 + k3 v^4/4."""
    return k1 * v * v / 2.0 + k2 * abs(v) ** 3 / 3.0 + k3 * v ** 4 / 4.0


def restoring_torque(delta, x, mu, k1, k2, k3):
    """Gamma(delta, x) = mu sum k_i sgn(delta)|delta|^i + (1 - mu) sum k_i sgn(x)|x|^i (Eq. 16)."""
    return mu * _stiffness_polynomial(delta, k1, k2, k3) + (1.0 - mu) * _stiffness_polynomial(x, k1, k2, k3)


def boucwen_rate(x, d_sign, a, beta, gamma, n):
    """dx/d delta of Eq. 17 for motion in direction d_sign: A - (beta sgn(dd) sgn(x) + gamma)|x|^n."""
    return a - (beta * d_sign * sgn(x) + gamma) * abs(x) ** n


def boucwen_step(x, ddelta, a, beta, gamma, n):
    """Backward Euler x' = x + dd g(x') for Eq. 17, one Newton iteration per piece, with the
    increment cut into pieces of at most x_u/10 (x_u = (A/(beta+gamma))^(1/n)).

    At x = 0 the piece enters the branch sgn(x) = sgn(dd); g's x-derivative
    -(beta sgn(dd) sgn(x) + gamma) n |x|^(n-1) sgn(x) is then that branch's (0 for n > 1).
    """
    if ddelta == 0.0:
        return x
    pieces = 1
    if beta + gamma > 0.0:
        xu = (a / (beta + gamma)) ** (1.0 / n)
        pieces = min(int(abs(ddelta) * a / (0.1 * xu)) + 1, 10000)
    dd = ddelta / pieces
    d = sgn(dd)
    for _ in range(pieces):
        sx = sgn(x) if x != 0.0 else d
        g = boucwen_rate(x, d, a, beta, gamma, n)
        if x == 0.0 and n != 1.0:
            slope = 0.0
        else:
            slope = -(beta * d * sx + gamma) * n * abs(x) ** (n - 1.0) * sx
        x = x + dd * g / (1.0 - dd * slope)
    return x


# ---- Transmission, Eqs. 7 and 18 with backlash ---------------------------------------------
def engaged(delta, backlash):
    """Deflection beyond the dead zone [-b/2, b/2] (the teeth are in contact only outside it)."""
    half = backlash / 2.0
    return max(delta - half, 0.0) + min(delta + half, 0.0)


def transmission_torque(delta, ddelta, x, mu, k1, k2, k3, damping, backlash):
    """T = Gamma(delta_e, x) + D delta' while the teeth are engaged (Eq. 18), 0 inside the gap."""
    de = engaged(delta, backlash)
    if backlash > 0.0 and abs(delta) <= backlash / 2.0:
        return 0.0
    return restoring_torque(de, x, mu, k1, k2, k3) + damping * ddelta


# ---- Load bearing and motor ripple ----------------------------------------------------------
def bearing_friction(w, fc, viscous, v_eps):
    """F_c sgn(w) + d_f w (Sec. 2.3), sgn regularised by tanh(w / v_eps) where v_eps > 0."""
    return fc * (math.tanh(w / v_eps) if v_eps > 0 else sgn(w)) + viscous * w


def bearing_step(v, hj, fc, viscous, v_eps):
    """Backward Euler for the bearing on a dof of h/J = hj: the end velocity w1 solves
    w1 + hj F(w1) = v (F's sign set-valued at 0 when v_eps = 0); returns F, at w1 where it slides.
    The root by bisection on the increasing left side, 200 halvings."""
    if hj <= 0:
        return 0.0
    if v_eps == 0 and abs(v) <= hj * fc:
        return v / hj  # sticks: w1 = 0

    def g(w):
        return w + hj * bearing_friction(w, fc, viscous, v_eps) - v

    lo, hi = sorted((0.0, v))
    if v_eps == 0:  # off zero the exact sign is the side of v
        lo, hi = (max(lo, 1e-300), hi) if v > 0 else (lo, min(hi, -1e-300))
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if g(mid) > 0:
            hi = mid
        else:
            lo = mid
    return bearing_friction(0.5 * (lo + hi), fc, viscous, v_eps)


def ripple_torque(q, amplitude, harmonic, phase):
    """A sin(k q + phi): k cycles per motor revolution."""
    return amplitude * math.sin(harmonic * q + phase)


# ---- The joint: Eqs. 4, 6, 18 and the load balance ---------------------------------------
@dataclass
class JointState:
    z1: float = 0.0
    z2: float = 0.0
    omega: float = 0.0
    q_r: float = 0.0
    w_sign: float = 0.0
    x: float = 0.0
    pending: tuple | None = None  # 2SEP states where a substepped step ends (joint_forces)
    load: float = 0.0  # what the last evaluation's transmission torque added to 2SEP's levels

    def as_list(self) -> list[float]:
        return [self.z1, self.z2, self.omega, self.q_r, self.w_sign, self.x]


def static_friction_slope(w, fc, fs, vs, shape, sigma, asym, v_eps, sigma_asym):
    """dF/dw of the regularised static map F = d L(w) + sigma (1 + sigma_asym d) w, d = tanh(w/v_eps),
    L = Fc + asym d + (Fs - Fc) exp(-|w/Vs|^shape), by the product and chain rules."""
    d = math.tanh(w / v_eps)
    dd = (1.0 - d * d) / v_eps
    r = abs(w) / vs
    decay = math.exp(-r ** shape)
    level = fc + asym * d + (fs - fc) * decay
    # d/dw exp(-r^shape) = -exp(-r^shape) shape r^(shape-1) sgn(w) / Vs; d times it vanishes at w = 0
    dlevel = asym * dd + ((fs - fc) * -decay * shape * r ** (shape - 1.0) * sgn(w) / vs if r > 0 else 0.0)
    return dd * level + d * dlevel + sigma * (1.0 + sigma_asym * d) + sigma * sigma_asym * dd * w


def _transmitted(p: JointParams, s: JointState, q, wq, theta, wtheta) -> float:
    t = p.transmission
    n = t.gear_ratio
    return transmission_torque(q / n - theta, wq / n - wtheta, s.x, t.mu, t.k1, t.k2, t.k3,
                               t.damping, t.backlash)


def stiffness_limit(p: JointParams, s: JointState, q, wq, theta, wtheta, h, hj, hjl, t, other):
    """The transmission's stiffness above 3 J_rel / h^2 (J_rel: motor and link inertias in series,
    1/J = hj/h) taken position-implicitly: its torque (k - k_lim) h rate1 at the deflection rate
    rate1 the step ends with, J_rel (rate1 - rate) / h = other - t - (k - k_lim) h rate1, where t
    is the spring's torque and ``other`` the rest on the deflection (NaN: unknown, taken as t)."""
    tr = p.transmission
    n = tr.gear_ratio
    de = engaged(q / n - theta, tr.backlash)
    r = h * (hj / n ** 2 + hjl)  # h^2 / J_rel
    if r <= 0 or (de == 0.0 and tr.backlash > 0):
        return 0.0
    bw = tr.hysteresis

    def tangent(v):  # d/dv of k1 v + k2 v|v| + k3 v^3
        return tr.k1 + 2 * tr.k2 * abs(v) + 3 * tr.k3 * v * v

    k = tr.mu * tangent(de) + (1 - tr.mu) * (bw.a if bw is not None else 1.0) * tangent(s.x)
    excess = k - 3.0 / r
    if excess <= 0:
        return 0.0
    if math.isnan(other):
        other = t
    j_rel = h * h / r
    rate1 = (j_rel * (wq / n - wtheta) / h + other - t) / (j_rel / h + excess * h)
    return excess * h * rate1


def joint_forces(p: JointParams, s: JointState, q, wq, theta, wtheta, h, hj, hjl, other=math.nan,
                 other_t=math.nan, other_l=math.nan):
    """(motor, link) generalised forces: u side m q'' = -T/N - f + r, link M theta'' = T - F_L.

    The motor's torque is taken at the velocity w1 its step ends with: w1 = wq + hj (other +
    f(w1)) with f linear in w1 (its velocity slopes at wq: friction, the engaged teeth's damping
    D/N^2, and the 2SEP lag damper B|z2|, which acts only if w1 has z2's sign). ``other``: the
    motor's other torques; unknown (NaN), those balancing f without the lag.
    """
    t = _transmitted(p, s, q, wq, theta, wtheta)
    t += stiffness_limit(p, s, q, wq, theta, wtheta, h, hj, hjl, t, other_t)
    tr = p.transmission
    n = tr.gear_ratio
    f = p.friction
    explicit = -t / n + (ripple_torque(q, p.ripple.amplitude, p.ripple.harmonic, p.ripple.phase)
                         if p.ripple is not None else 0.0)
    engaged_teeth = tr.backlash == 0.0 or engaged(q / n - theta, tr.backlash) != 0.0
    damping = -(tr.damping if engaged_teeth else 0.0) / n ** 2
    # load-dependent friction: both levels raised by load_gain |T| / N
    load = f.load_gain * abs(t) / n if f is not None else 0.0
    if isinstance(f, StaticFriction) and f.v_eps == 0 and hj > 0:
        # the exact sign: (1 - damping hj) w1 + hj S(w1) = (1 - damping hj) wq + hj (other + explicit)
        args = (f.fc + load, f.fs + load, f.vs, f.shape, f.sigma, f.asym, f.sigma_asym)
        if math.isnan(other):
            other = -(explicit - steady_state(wq, *args))
        k = 1.0 - damping * hj
        a = k * wq + hj * (other + explicit)
        w1, fric = static_friction_step(a, k, hj, *args)
        motor = explicit + damping * (w1 - wq) - fric
        return motor, _link(p, t, wtheta, hjl, other_l)
    if isinstance(f, TwoSEP):
        if f.load_gain != 0.0:
            presliding_level(f, s, s.load, load)
        if math.isnan(other):
            other = -(explicit - s.z1)
        w1, fric = twosep_velocity(f, s.z1, s.z2, explicit, damping, other, wq, hj)
        s.pending = None
        s.load = load
        if hj > 0 and twosep_event(f, s.w_sign, wq, w1):
            *end, = twosep_substeps(f, s.z1, s.z2, s.omega, s.q_r, s.w_sign, explicit, damping, other, wq, h, hj,
                                    SUBSTEPS, load)
            w1, s.pending = end[0], tuple(end[1:])
            # the torque that lands the update w1 = wq + hj (other + torque) where the substeps end
            return (w1 - wq) / hj - other, _link(p, t, wtheta, hjl, other_l)
        return explicit + damping * (w1 - wq) - fric, _link(p, t, wtheta, hjl, other_l)
    base, slope = 0.0, 0.0
    if isinstance(f, StaticFriction):
        args = (f.fc + load, f.fs + load, f.vs, f.shape, f.sigma, f.asym, f.v_eps, f.sigma_asym)
        base = static_friction(wq, *args)
        slope = max(0.0, static_friction_slope(wq, *args)) if f.v_eps > 0 else 0.0
    motor = explicit - base
    g = damping - slope
    if math.isnan(other):
        other = -motor
    # w1 (1 - g hj) = wq (1 - g hj) + hj (other + motor).
    w1 = wq + hj * (other + motor) / (1.0 - g * hj)
    motor = motor + g * (w1 - wq)
    return motor, _link(p, t, wtheta, hjl, other_l)


def presliding_level(f: TwoSEP, s: JointState, load_from, load_to):
    """The pre-sliding curve (z1 and Omega) scaled from levels raised by ``load_from`` to
    ``load_to``, as the Coulomb level in the motion's direction scales."""
    base = f.fc + f.asym * s.w_sign
    r = (base + load_to) / (base + load_from)
    s.z1 *= r
    s.omega *= r


def twosep_velocity(f: TwoSEP, z1, z2, explicit, g, other, wq, hj):
    """(w1, friction) over a step: w1 = wq + hj (other + explicit + g (w1 - wq) - F), F = z1 + c w1,
    z1 the step's start's, the lag damper c = B|z2| where z2 has the sign of the w1 reached without
    it."""
    k = 1.0 - g * hj
    w1 = wq + hj * (other + (explicit - z1)) / k
    c = f.b * abs(z2) if sgn(z2) == sgn(w1) != 0 else 0.0
    w1 = (wq * k + hj * (other + (explicit - z1))) / (k + c * hj)
    return w1, z1 + c * w1


def twosep_event(f: TwoSEP, w_sign, wq, w1):
    """A reversal, or the rotor slower than EVENT_SPEED Stribeck velocities at either end."""
    return (w1 != 0 and sgn(w1) != w_sign) or min(abs(wq), abs(w1)) < EVENT_SPEED * f.vs


def twosep_substeps(f: TwoSEP, z1, z2, omega, q_r, w_sign, explicit, g, other, wq, h, hj, n, load=0.0):
    """n steps of h / n, each ``twosep_velocity`` then ``twosep_step``, under the frozen drive
    other + explicit + g (w - wq), the levels raised by ``load``. Returns (w1, z1, z2, omega, q_r,
    w_sign)."""
    w = wq
    for _ in range(n):
        w, _ = twosep_velocity(f, z1, z2, explicit + g * (w - wq), g, other, w, hj / n)
        z1, z2, omega, q_r, w_sign = twosep_step(z1, z2, omega, q_r, w_sign, w, h / n, f.fc + load, f.fs + load,
                                                 f.vs, f.shape, f.sigma, f.k, f.b, f.asym, f.sigma_asym)
    return w, z1, z2, omega, q_r, w_sign


def _link(p: JointParams, t, wtheta, hjl, other_l):
    """The link's generalised force, T less the bearing taken at the link velocity the step ends
    with; ``other_l``: the link's other torques (NaN: unknown, those balancing T)."""
    link = t
    if p.load_friction is not None:
        lf = p.load_friction
        if hjl > 0:
            rest = -link if math.isnan(other_l) else other_l
            link -= bearing_step(wtheta + hjl * (rest + link), hjl, lf.fc, lf.viscous, lf.v_eps)
        else:
            link -= bearing_friction(wtheta, lf.fc, lf.viscous, lf.v_eps)
    return link


def joint_advance(p: JointParams, s: JointState, q, wq, theta, wtheta, h) -> JointState:
    """States after a semi-implicit Euler step that ended at (q, theta) with velocities (wq, wtheta)."""
    out = JointState(*s.as_list())
    f = p.friction
    if isinstance(f, TwoSEP) and s.pending is not None:  # substepped by joint_forces: where that ended
        out.z1, out.z2, out.omega, out.q_r, out.w_sign = s.pending
    elif isinstance(f, TwoSEP):
        out.z1, out.z2, out.omega, out.q_r, out.w_sign = twosep_step(
            s.z1, s.z2, s.omega, s.q_r, s.w_sign, wq, h, f.fc + s.load, f.fs + s.load, f.vs, f.shape, f.sigma, f.k,
            f.b, f.asym, f.sigma_asym)
    hyst = p.transmission.hysteresis
    if hyst is not None:
        n = p.transmission.gear_ratio
        bl = p.transmission.backlash
        end = q / n - theta
        start = (q - wq * h) / n - (theta - wtheta * h)
        out.x = boucwen_step(s.x, engaged(end, bl) - engaged(start, bl), hyst.a, hyst.beta, hyst.gamma, hyst.n)
    return out
