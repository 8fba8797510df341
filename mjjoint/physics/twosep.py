"""2SEP dynamic friction (two-state with elasto-plasticity), Ruderman 2012 Eqs. 11-15.

    F = A z1 + B |w| z2                                  (11), A = 1 as the chapter suggests
    z1' = |Omega| w K exp(-K |q_r|)                      (12)
    Omega = sgn(w) Fc - F   at each velocity reversal    (13), q_r reset to 0 there
    z2' = (S(w) - F) / |S(w)|                            (14)
    S(w) = s(w) + sigma w,  s(w) Stribeck curve          (15)

What the equations mean where the chapter is silent (each choice made once, here):
- |S(w)| in (14) is the curve's magnitude, |s| + sigma|w| >= Fc > 0: the literal |S(0)| = 0
  would divide by zero where B|w|z2 vanishes anyway.
- The sgn(w) of S in (14) is regularised, tanh(w / (SIGN_WIDTH Vs)) (``lag_target``). With the
  literal sign, z2's drive jumps between (Fs - z1)/Fs and (-Fs - z1)/Fs with every sign change of
  w, so at rest the windup of z2 was decided by velocity chatter far below any encoder count
  (and by the timestep that resolves it): the model had no converged solution in stick phases.
  The regularised drive is continuous; at rest z2 follows -z1/|S|, the chatter's average.
- Omega (13) is taken with F = z1, its value at the instant w crosses zero (evaluating F at
  the new, non-zero velocity would let a velocity jump leak B|w|z2 into the pre-sliding memory).
- The lag term B|w|z2 of (11) acts only while it opposes the motion (z2 w > 0). During slow
  sliding z2's steady value (S - Fc)/(B|w|) grows as |w| falls, and right after a reversal the
  literal term would push along the new motion, injecting energy (a free rotor gained ~10 J in
  a kernel-only run). z2 itself evolves by (14) unchanged, so the frictional lag and its growth
  with frequency (Fig. 8) are kept.
Together these fix the friction at breakaway and in slow sliding: under a constant velocity F
settles on S(w) from ten sign widths (0.5 rad/s for the defaults) on, and below that on
max(|S_reg(w)|, Fc) (``TwoSEP.steady_friction``). At rest the lag winds up against the load,
so a breakaway starts from the saturated pre-sliding force and the lag builds up towards S(w)
as the rotor gains speed: a drive above Fs breaks the rotor free, at any timestep.

Integration over one step of length h (once per MuJoCo step, at the start of the next):
z1 is integrated exactly in the displacement domain, since (12) is w times a function of q_r
alone: z1 += sgn(w)|Omega| (e^{-K|q_r|} - e^{-K|q_r + w h|}). (14) is linear in z2 for the
step's w and z1, z2' = d - lam z2 with lam = B|w|/|S|, and is solved exactly over the step
(stiff at speed, where 1/lam is far below h). In MuJoCo the lag force is a damper of slope
B|z2| on the rotor, unbounded in slow sliding; the plugin applies it linearly implicitly with
the rotor's other torques (``coupling.kernels.joint_evaluate``), so the pair is integrated
consistently at any slope. z1 is applied as the step's start holds it. A step that holds a
reversal, a stop or a breakaway is taken in substeps of the rotor and these states together
(``coupling.kernels.twosep_substeps``; docs/design.md, "Integration").
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..params import check
from .jit import kernel
from .stribeck import smooth_sign, steady_state, stribeck_level  # noqa: F401 (steady_state: public API)

# Width of the regularised sgn(w) in the lag state's drive (Eq. 14), in Stribeck velocities.
SIGN_WIDTH = 0.1


@kernel
def twosep_force(z1: float, z2: float, w: float, b: float) -> float:
    """Friction torque F = z1 + B|w|z2 (Eq. 11 with A = 1); the lag term only when it opposes w."""
    return z1 + b * abs(w) * z2 if z2 * w > 0.0 else z1


@kernel
def lag_target(w, fc, fs, vs, shape, sigma, asym, sigma_asym):
    """(S, |S|): the steady state that drives the lag state (Eq. 14) and its magnitude.

    S's sgn(w) is regularised over ``SIGN_WIDTH`` Stribeck velocities, so z2's drive is
    continuous at w = 0; |S| is the curve's magnitude, >= Fc > 0 (the literal |S(0)| = 0).
    """
    sg = 1.0 if w > 0.0 else (-1.0 if w < 0.0 else 0.0)
    level = stribeck_level(w, fc + asym * sg, fs + asym * sg, vs, shape)
    slope = sigma * (1.0 + sigma_asym * sg)
    return smooth_sign(w, SIGN_WIDTH * vs) * level + slope * w, level + slope * abs(w)


# Past K|q_r| = 40 the pre-sliding increment is below omega e^-40 = 4e-18 omega, under z1's
# last bit: |q_r| only grows between reversals, so its exp() are skipped from there on.
SATURATED = 40.0


@kernel
def presliding_unspent(qr, k):
    """e^{-K|q_r|}, the pre-sliding spring's unspent share (Eq. 12), 0 once saturated."""
    return math.exp(-k * abs(qr)) if k * abs(qr) < SATURATED else 0.0


@kernel
def presliding_from(z1, omega, qr, wsign, w, h, fc, k, asym, unspent):
    """Eqs. 12-13 over one step at velocity ``w``, given ``unspent`` = ``presliding_unspent(qr, k)``,
    which a caller that steps on carries from each step's end to the next (one exp a step instead
    of two): (z1, omega, qr, wsign, unspent) at the step's end."""
    sg = 1.0 if w > 0.0 else (-1.0 if w < 0.0 else 0.0)
    if sg != 0.0 and sg != wsign:
        # Motion reversal: memorise the stiffness capacity (13) and restart q_r. At the
        # reversal w crosses 0, so F = z1 there.
        omega = abs(sg * (fc + asym * sg) - z1)
        qr = 0.0
        wsign = sg
        unspent = 1.0
    qr_new = qr + w * h
    if k * abs(qr) < SATURATED:
        end = math.exp(-k * abs(qr_new))
        z1 = z1 + sg * omega * (unspent - end)
        unspent = end if k * abs(qr_new) < SATURATED else 0.0
    return z1, omega, qr_new, wsign, unspent


@kernel
def reverses(w, wsign):
    """Whether moving at ``w`` reverses the motion last in direction ``wsign``."""
    return w != 0.0 and (1.0 if w > 0.0 else -1.0) != wsign


@kernel
def twosep_step(z1, z2, omega, qr, wsign, w, h, fc, fs, vs, shape, sigma, k, b, asym, sigma_asym):
    """Advance the 2SEP states over one step at velocity ``w``; returns (z1, z2, omega, qr, wsign)."""
    z1, z2, omega, qr, wsign, _ = twosep_step_from(z1, z2, omega, qr, wsign, w, h, fc, fs, vs, shape, sigma, k, b,
                                                   asym, sigma_asym, presliding_unspent(qr, k))
    return z1, z2, omega, qr, wsign


@kernel
def twosep_step_from(z1, z2, omega, qr, wsign, w, h, fc, fs, vs, shape, sigma, k, b, asym, sigma_asym, unspent):
    """``twosep_step`` given ``presliding_unspent(qr, k)`` (``presliding_from``); returns it at the
    step's end after the five states."""
    z1, omega, qr_new, wsign, unspent = presliding_from(z1, omega, qr, wsign, w, h, fc, k, asym, unspent)
    s, s_mag = lag_target(w, fc, fs, vs, shape, sigma, asym, sigma_asym)
    # Eq. 14 is linear in z2 for frozen w and z1: z2' = d - lam z2, solved exactly over the step.
    # The gain (1 - e^-lam_h) h / lam_h from the one exp; its series where that loses digits, and
    # no exp at all where e^-lam_h is below z2's last bit (fast sliding).
    lam_h = h * b * abs(w) / s_mag
    if lam_h > 40.0:
        decay, gain = 0.0, h / lam_h
    elif lam_h > 1e-4:
        decay = math.exp(-lam_h)
        gain = h * (1.0 - decay) / lam_h
    else:
        decay, gain = 1.0 - lam_h * (1.0 - 0.5 * lam_h), h * (1.0 - lam_h * (0.5 - lam_h / 6.0))
    z2 = z2 * decay + gain * (s - z1) / s_mag
    return z1, z2, omega, qr_new, wsign, unspent


@dataclass(frozen=True)
class TwoSEP:
    """Parameters of the 2SEP model: the seven of the chapter, optional asymmetries and load dependence.

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
    # Both levels grow by load_gain |T| / N, T the torque the gear transmits, as
    # StaticFriction.load_gain; the pre-sliding saturates at the raised level. The methods below
    # give the map at T = 0.
    load_gain: float = 0.0

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
        check("load_gain", self.load_gain, 0.0, 1.0, hi_open=True)

    def steady_state(self, w: float) -> float:
        """S(w) of Eqs. 14-15, the chapter's steady-state map."""
        return steady_state(w, self.fc, self.fs, self.vs, self.shape, self.sigma, self.asym, self.sigma_asym)

    def steady_friction(self, w: float) -> float:
        """The friction the model settles at under a constant velocity w: the lag's target where it
        exceeds the saturated pre-sliding force sgn(w)(Fc + asym sgn w), that force elsewhere (the
        lag only opposes the motion). S(w) itself from ten ``SIGN_WIDTH`` on."""
        target, _ = lag_target(w, self.fc, self.fs, self.vs, self.shape, self.sigma, self.asym, self.sigma_asym)
        sg = math.copysign(1.0, w) if w != 0 else 0.0
        presliding = sg * (self.fc + self.asym * sg)
        return target if abs(target) > abs(presliding) else presliding
