"""Static friction maps: Coulomb, viscous and the Stribeck curve (Ruderman 2012, Eq. 15).

``StaticFriction`` is the simple alternative to 2SEP: a memoryless map of velocity whose sign
is regularised by ``tanh(w / v_eps)`` so that MuJoCo integrates it without chattering.
Coulomb-only and viscous-only friction are special cases (see the constructors).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..params import check
from .jit import kernel
from .roots import ITERATIONS, newton_in_bracket


@kernel
def smooth_sign(w: float, v_eps: float) -> float:
    """tanh(w / v_eps), the regularised sgn(w) of the static maps.

    Written with one expm1(), (1 - e^-x) / (1 + e^-x) without the cancellation of 1 - e^-x at
    small x (relative accuracy there matters to the map's slope), and cheaper than libm's tanh
    (this runs every simulation step).
    """
    x = 2.0 * abs(w / v_eps)
    if x > 40.0:  # e^-40 = 4e-18: 1 to the last bit, without the exp (sliding, most steps)
        return 1.0 if w >= 0.0 else -1.0
    em = math.expm1(-x)
    t = -em / (2.0 + em)
    return t if w >= 0.0 else -t


@kernel
def stribeck_level(w: float, fc: float, fs: float, vs: float, shape: float) -> float:
    """Magnitude of the Stribeck curve: Fc + (Fs - Fc) exp(-|w/Vs|^shape) (Eq. 15 without sign)."""
    r = abs(w / vs)
    # the common shapes 1 and 2 without pow(): this runs every simulation step
    e = r if shape == 1.0 else (r * r if shape == 2.0 else r ** shape)
    # past e = 40 the Stribeck bump, (Fs - Fc) 4e-18, is below the Coulomb level's last bit
    return fc + (fs - fc) * math.exp(-e) if e < 40.0 else fc


@kernel
def steady_state(w: float, fc: float, fs: float, vs: float, shape: float, sigma: float,
                 asym: float, sigma_asym: float) -> float:
    """S(w) = s(w) + sigma w (Eqs. 14-15); ``asym`` shifts both levels in the direction of motion,
    ``sigma_asym`` scales the viscous slope by (1 + sigma_asym sgn w)."""
    sg = 1.0 if w > 0.0 else (-1.0 if w < 0.0 else 0.0)
    return sg * stribeck_level(w, fc + asym * sg, fs + asym * sg, vs, shape) + sigma * (1.0 + sigma_asym * sg) * w


@kernel
def static_friction(w: float, fc: float, fs: float, vs: float, shape: float, sigma: float,
                    asym: float, v_eps: float, sigma_asym: float) -> float:
    """Regularised static map: tanh(w/v_eps) replaces sgn(w) in S(w); v_eps = 0: S(w) itself,
    0 at w = 0 (at rest the exact sign is set-valued: ``static_friction_step`` decides)."""
    if v_eps <= 0.0:
        return steady_state(w, fc, fs, vs, shape, sigma, asym, sigma_asym)
    sg = smooth_sign(w, v_eps)
    return sg * stribeck_level(w, fc + asym * sg, fs + asym * sg, vs, shape) + sigma * (1.0 + sigma_asym * sg) * w


@kernel
def static_friction_step(a: float, k: float, hj: float, fc: float, fs: float, vs: float, shape: float,
                         sigma: float, asym: float, sigma_asym: float):
    """The exact static map over a step, taken at the velocity w1 the step ends with (backward
    Euler): k w1 + hj S(w1) = a, with S's sign set-valued at rest. ``a``: k times the velocity
    the step would end with without the friction; ``k`` >= 1 carries the dof's other linearly
    implicit slopes; ``hj`` = h / J. Returns (w1, the friction torque).

    The dof holds at rest while the drive a / hj lies within the break-away levels
    [-(Fs - asym), Fs + asym], and the friction applies what stops it; otherwise it slides in
    the drive's direction, where k w + hj S(w) - a, increasing but for the Stribeck dip, changes
    sign between 0 and a / k (S's level at rest is the break-away one): Newton within that
    bracket (``roots``). The dip can give several roots; the one found is inside the bracket.
    """
    if hj <= 0.0:
        return a / k, 0.0
    if -hj * (fs - asym) <= a <= hj * (fs + asym):
        return 0.0, a / hj
    sg = 1.0 if a > 0.0 else -1.0
    lo = 0.0
    hi = a / k
    if hi < lo:
        lo, hi = hi, lo
    slope = k + hj * sigma * (1.0 + sigma_asym * sg)
    w = 0.5 * (lo + hi)
    for _ in range(ITERATIONS):
        g = slope * w + hj * sg * stribeck_level(w, fc + asym * sg, fs + asym * sg, vs, shape) - a
        r = abs(w / vs)
        e = r if shape == 1.0 else (r * r if shape == 2.0 else r ** shape)
        # d level / dw on the sliding side: -(Fs - Fc) E shape r^(shape-1) sg / vs
        dlevel = -(fs - fc) * math.exp(-e) * shape * e / r / vs * sg if r > 0.0 and e < 40.0 else 0.0
        w, lo, hi, done = newton_in_bracket(w, g, slope + hj * sg * dlevel, lo, hi)
        if done:
            break
    return w, sg * stribeck_level(w, fc + asym * sg, fs + asym * sg, vs, shape) + sigma * (1.0 + sigma_asym * sg) * w


@kernel
def static_friction_slope(w: float, fc: float, fs: float, vs: float, shape: float, sigma: float,
                          asym: float, v_eps: float, sigma_asym: float) -> float:
    """dF/dw of ``static_friction``: what makes the map stiff near w = 0 (fc / v_eps there).

    With d = tanh(w/v_eps) and E = exp(-|w/Vs|^shape) the map is
    F = d (Fc + asym d + (Fs - Fc) E) + sigma (1 + sigma_asym d) w, so
    F' = d' (Fc + 2 asym d + (Fs - Fc) E + sigma sigma_asym w) + d (Fs - Fc) E' + sigma (1 + sigma_asym d).
    """
    d = smooth_sign(w, v_eps)
    r = abs(w / vs)
    e = r if shape == 1.0 else (r * r if shape == 2.0 else r ** shape)
    big_e = math.exp(-e) if e < 40.0 else 0.0
    dd = (1.0 - d * d) / v_eps
    # d E' = -|d| E shape r^(shape-1) / Vs: finite at w = 0 since |d| ~ |w| / v_eps there
    de = abs(d) * big_e * shape * e / r / vs if r > 0.0 else 0.0
    return (dd * (fc + 2.0 * asym * d + (fs - fc) * big_e + sigma * sigma_asym * w)
            - (fs - fc) * de + sigma * (1.0 + sigma_asym * d))


@dataclass(frozen=True)
class StaticFriction:
    """Memoryless motor friction F(w) = sgn_eps(w)(Fc + (Fs-Fc) e^{-|w/Vs|^shape}) + sigma w.

    Units are motor side: torques in N·m, velocities in rad/s.
    """

    fc: float = 0.08      # Coulomb level; same default as TwoSEP.fc
    fs: float = 0.12      # break-away level; same default as TwoSEP.fs
    vs: float = 0.5       # Stribeck velocity; same default as TwoSEP.vs
    shape: float = 1.0    # Stribeck shape factor; same default as TwoSEP.shape
    sigma: float = 2e-4   # viscous coefficient; same default as TwoSEP.sigma
    asym: float = 0.0     # direction-dependent shift of both levels (friction asymmetry)
    # Direction-dependent viscous slope: sigma (1 + sigma_asym sgn w), |sigma_asym| < 1 keeps it
    # dissipative. 0: symmetric, as the chapter's model (EMPS: slopes 155 / 231 N s/m, docs/datasets.md).
    sigma_asym: float = 0.0
    # Sign regularisation [rad/s]; 0: the exact sign (the rotor sticks below break-away; stable
    # at any step, ``static_friction_step``). A positive value is linearised on the rotor, so the
    # slope fc/v_eps on the rotor inertia J must keep fc h/(v_eps J) < 2: 1 rad/s suits fc = 0.08
    # N m, J = 5e-5 kg m^2, h = 0.5 ms (and is 0.3 % of the 325 rad/s idling speed).
    v_eps: float = 1.0
    # Load-dependent friction: both levels grow by load_gain |T| / N, T the torque the gear
    # transmits (gear teeth and bearings pressed by the load; an efficiency below one). 0: the
    # chapter's load-independent map. The map of a call (``__call__``) is the one at T = 0.
    load_gain: float = 0.0

    def __post_init__(self) -> None:
        check("fc", self.fc, 0.0)
        check("fs", self.fs, 0.0)
        check("vs", self.vs, 0.0, lo_open=True)
        check("shape", self.shape, 0.1, 5.0)
        check("sigma", self.sigma, 0.0)
        lim = min(self.fc, self.fs)  # both directions keep non-negative friction levels
        check("asym", self.asym, -lim, lim)
        check("sigma_asym", self.sigma_asym, -1.0, 1.0, lo_open=True, hi_open=True)
        check("v_eps", self.v_eps, 0.0)
        check("load_gain", self.load_gain, 0.0, 1.0, hi_open=True)

    @classmethod
    def coulomb(cls, fc: float, v_eps: float = 1.0) -> "StaticFriction":
        return cls(fc=fc, fs=fc, sigma=0.0, v_eps=v_eps)

    @classmethod
    def viscous(cls, sigma: float) -> "StaticFriction":
        return cls(fc=0.0, fs=0.0, sigma=sigma)

    def __call__(self, w: float) -> float:
        return static_friction(w, self.fc, self.fs, self.vs, self.shape, self.sigma, self.asym, self.v_eps,
                               self.sigma_asym)
