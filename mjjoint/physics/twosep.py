"""2SEP dynamic friction (two-state with elasto-plasticity), Ruderman 2012 Eqs. 11-15.

    F = A z1 + B |w| z2                                  (11), A = 1 as the chapter suggests
    z1' = |Omega| w K exp(-K |q_r|)                      (12)
    Omega = sgn(w) Fc - F   at each velocity reversal    (13), q_r reset to 0 there
    z2' = (S(w) - F) / |S(w)|                            (14)
    S(w) = s(w) + sigma w,  s(w) Stribeck curve          (15)

Integration over one step of length h (done once per MuJoCo step, in the plugin's advance):
z1 is integrated *exactly* in the displacement domain, since (12) is w times a function of
q_r alone: z1 += sgn(w)|Omega| (e^{-K|q_r|} - e^{-K|q_r + w h|}). z2 is stepped linearly
implicitly, because the attraction rate B|w|/|S| becomes stiff at speed. |S(w)| in (14) is
taken as the magnitude of the curve, |s| + sigma|w| >= Fc > 0, which equals |S(w)| for w != 0
and avoids the division by zero the literal formula has at w = 0 (where B|w|z2 = 0 anyway).

Two readings keep the model passive. Omega (13) is taken with F = z1, its value at the instant
w crosses zero (evaluating F at the new, non-zero velocity would let a velocity jump leak
B|w|z2 into the pre-sliding memory). And the lag term B|w|z2 of (11) acts only while it
opposes the motion (z2 w > 0): during slow sliding z2's steady value (S - Fc)/(B|w|) grows as
|w| falls, and right after a reversal the literal term would push ALONG the new motion,
injecting energy (a free rotor gained ~10 J in a kernel-only run). z2 itself evolves by (14)
unchanged, so the frictional lag and its growth with frequency (Fig. 8) are kept: the lag-loop
areas at 0.3-10 Hz differ from the literal form's by < 4 %. In MuJoCo the lag force is applied
linearly implicitly (``twosep_force_implicit``): it is a damper of unbounded slope in slow
sliding, which explicit integration turns into a limit cycle.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..params import check
from .jit import kernel
from .stribeck import steady_state, stribeck_level  # noqa: F401 (steady_state: public API)

# Layout of the 2SEP state inside the plugin state vector.
Z1, Z2, OMEGA, QR, WSIGN = range(5)
NSTATE = 5


@kernel
def twosep_force(z1: float, z2: float, w: float, b: float) -> float:
    """Friction torque F = z1 + B|w|z2 (Eq. 11 with A = 1); the lag term only when it opposes w."""
    return z1 + b * abs(w) * z2 if z2 * w > 0.0 else z1


@kernel
def twosep_force_implicit(z1: float, z2: float, w: float, b: float, hj: float) -> float:
    """``twosep_force`` with the lag term taken linearly implicitly over a step h on an inertia J.

    While it acts, the lag term is a damper c w with c = B|z2|, and c grows without bound in slow
    sliding (z2 -> (S - z1)/(B|w|)). Applied explicitly it destabilises the inertia once
    c h / J > 2: a kicked free rotor kept a ~680 Hz dither (rms 0.06 rad/s at h = 0.5 ms,
    c up to 0.47 N m s/rad against a limit of 0.2). Taken at the velocity the step ends with,
    the damper of a backward-Euler step on J is c w / (1 + c h/J): stable for any c, and equal to
    ``twosep_force`` as h/J -> 0. ``hj`` = h/J, J the dof's apparent inertia. The price: at the
    step, slow sliding (c h/J >~ 1) reaches less than the lag's share of S(w).
    """
    if z2 * w <= 0.0:
        return z1
    c = b * abs(z2)
    return z1 + c * w / (1.0 + c * hj)


@kernel
def twosep_step(z1, z2, omega, qr, wsign, w, h, fc, fs, vs, shape, sigma, k, b, asym, sigma_asym):
    """Advance the 2SEP states over one step at velocity ``w``; returns (z1, z2, omega, qr, wsign)."""
    sg = 1.0 if w > 0.0 else (-1.0 if w < 0.0 else 0.0)
    if sg != 0.0 and sg != wsign:
        # Motion reversal: memorise the stiffness capacity (13) and restart q_r. At the
        # reversal w crosses 0, so F = z1 there.
        omega = abs(sg * (fc + asym * sg) - z1)
        qr = 0.0
        wsign = sg
    qr_new = qr + w * h
    # |q_r| only grows between reversals; past K|q_r| = 40 the increment is below
    # omega e^-40 = 4e-18 omega, under z1's last bit, so the two exp() are skipped (per step).
    if k * abs(qr) < 40.0:
        z1 = z1 + sg * omega * (math.exp(-k * abs(qr)) - math.exp(-k * abs(qr_new)))
    level = stribeck_level(w, fc + asym * sg, fs + asym * sg, vs, shape)
    slope = sigma * (1.0 + sigma_asym * sg)
    s_mag = level + slope * abs(w)
    s = sg * level + slope * w  # = steady_state(w, ...), without evaluating the curve twice
    z2 = (z2 + h * (s - z1) / s_mag) / (1.0 + h * b * abs(w) / s_mag)
    return z1, z2, omega, qr_new, wsign


@dataclass(frozen=True)
class TwoSEP:
    """Parameters of the 2SEP model: the seven of the chapter plus an optional asymmetry.

    Motor side: torques in N·m, velocities in rad/s, K in 1/rad, B in N·m/rad.
    Defaults describe a 400 W BLDC with a harmonic-drive wave generator as in the chapter's
    lab joint (Sec. 4); the chapter gives no numbers, so they are typical catalogue orders of
    magnitude: no-load running torque ~0.1 N·m at the input, break-away 1.5x Coulomb.
    """

    fc: float = 0.08      # Coulomb level [N·m]: harmonic-drive no-load running torque order
    fs: float = 0.12      # stiction level [N·m]: 1.5 x fc, a common break-away ratio
    vs: float = 0.5       # Stribeck velocity [rad/s] ~ 5 rpm at the motor
    shape: float = 1.0    # Stribeck shape factor delta (Eq. 15); 1 = exponential decay
    sigma: float = 2e-4   # viscous [N·m·s/rad]: 0.065 N·m at the 3100 rpm idling speed
    k: float = 1000.0     # pre-sliding stiffness K [1/rad]: 95 % of Fc within 3 mrad at the motor
    b: float = 50.0       # attraction gain B [N·m/rad]: lag time constant |S|/(B|w|) ~ 2 ms at 1 rad/s
    asym: float = 0.0     # direction-dependent shift of Fc and Fs [N·m]
    sigma_asym: float = 0.0  # viscous slope sigma (1 + sigma_asym sgn w); as StaticFriction.sigma_asym

    def __post_init__(self) -> None:
        check("fc", self.fc, 0.0, lo_open=True)
        check("fs", self.fs, 0.0, lo_open=True)
        check("vs", self.vs, 0.0, lo_open=True)
        check("shape", self.shape, 0.1, 5.0)
        check("sigma", self.sigma, 0.0)
        check("k", self.k, 0.0, lo_open=True)
        check("b", self.b, 0.0)
        lim = min(self.fc, self.fs)  # both directions keep positive friction levels
        check("asym", self.asym, -lim, lim, lo_open=True, hi_open=True)
        check("sigma_asym", self.sigma_asym, -1.0, 1.0, lo_open=True, hi_open=True)

    def steady_state(self, w: float) -> float:
        return steady_state(w, self.fc, self.fs, self.vs, self.shape, self.sigma, self.asym, self.sigma_asym)
