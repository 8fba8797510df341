"""Nominal values and ranges of the identification, estimated from the recording itself.

The effect catalogue (``effects``) gives every parameter an initial value and bounds in the
lab arm's orders (motor torques ~0.1 N m, motor speeds ~10 rad/s). A small servo or a 300 kg
robot axis lies decades away, and a fit started decades off or bounded short of the truth
cannot reach it. ``estimate`` measures the recording's own orders and the parameters a few
linear regressions give:

* force and speed orders: robust amplitudes (AMPLITUDE_PERCENTILE) of u and of the smoothed
  motor speed; the position order is what one second at that speed covers;
* motor inertia, Coulomb and viscous friction, input offset: least squares of the motor's
  equation u - tau/N = J a + Fc sgn(v) + d v - offset on the samples where the motor moves
  clearly (|v| > MOVING_SHARE of the speed order), every signal through one zero-phase
  low-pass (CUTOFF); a direct drive has no tau; a geared joint whose tau is not measured is taken as
  rigid (inertia J_m + J_l/N^2 and gravity columns), the sum split as the nominal arm's where it
  is of that size, else evenly between the sides (``_rigid_split``);
* gear stiffness: least squares of tau = k delta + D delta' + c with the deflection
  delta = q/N - theta where tau is measured, else from a resonance of the input-to-deflection
  response, k = J_red (2 pi f)^2 with the two sides' reduced inertia, else at the nominal's
  locked-link frequency;
* the encoders: the link encoder's lag and the deflection at zero gear torque, against the gear
  torque T (tau, or what the input leaves past the rotor's inertia): ``_encoder_lag`` (the start
  of ``sensor_skew``) and ``encoder_offset`` (two zeros the problem aligns before any fit);
* a play: its width and the stiffness beyond it from the engaged teeth (``engaged_gear``), a
  second start of the backlash's screen (``Estimate.play``), not a value every fit starts from.

``Estimate.param`` turns a catalogue parameter into the recording's: the catalogue values
scaled by the decade of each order (``scales``; the lab arm's are all 1, so its fits start as
before), and a directly estimated parameter started at its estimate with bounds DECADES either
side. All values are in the recording's (SI) units.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import butter, csd, filtfilt, welch

from ..sim import held_controls
from .effects import EFFECTS, Param

# The orders the catalogue's values are set for: the lab arm's, the geometric middle of its
# recordings' amplitudes (force [N m], speed [rad/s]: 0.16 and 46 for the 5 s default chirp,
# 0.17 and 23 for the multisine, 0.49 and 99 for the closed-loop lab program), so that all of
# them round to the catalogue's own decade; position: what one second at that speed covers,
# as the drives' ``scales`` define it.
CATALOGUE_ORDERS = {"force": 0.27, "speed": 47.0, "position": 47.0}
AMPLITUDE_PERCENTILE = 95.0
# Samples where |v| exceeds this share of the speed order enter the friction regression: there
# the sign of v is certain and the friction is on its sliding branch.
MOVING_SHARE = 0.1
# Low-pass of the regressions' signals [Hz]: the acceleration is a second derivative of an
# encoder angle; 50 Hz keeps a 20-bit encoder's steps at 1 kHz far below the motion.
CUTOFF = 50.0
CUTOFF_NYQUIST = 0.8  # at most this share of the Nyquist frequency
# A directly estimated parameter may move this many decades either way in the fit.
DECADES = 3.0
# The regularised Coulomb slope's step c h = Fc h / (v_eps J) a model is kept to: its plant's
# shipped model's, inside the explicit limit of 2. The drive's (linear_drive.xml: 0.21); the
# arm's (its 0.08 N m Coulomb level on the 5e-5 kg m^2 rotor at 0.5 ms, v_eps 1 rad/s: 0.8).
SLOPE_STEP = 0.2
ARM_SLOPE_STEP = 0.8
# A resonance counts as visible when the response's peak stands this far above its median, at
# frequencies where the input's power is above EXCITED of its peak (elsewhere H is noise).
PEAK_RATIO = 5.0
EXCITED = 1e-3
# The link is started from the recording (``_link_start``) where its estimated inertia lies this
# many decades or more from the nominal arm's: rounded to its decade, as the orders are.
LINK_DECADE = 0.5
# ... and only where the rigid link's equation explains this share of the link torque's variance:
# a bending rod or a gear's play breaks it, and its coefficients are then no estimates (a rod of
# 4 segments: 58 %, with a negative Coulomb level and a 200x bearing damping).
LINK_EXPLAINED = 0.9
STIFFNESS = EFFECTS["linear_stiffness"].params[0]
# A gear held on one side of its play by a steady load deflects by half the play at zero torque:
# an offset is taken for the encoders' only where its torque is this many times the recording's.
OFFSET_TORQUES = 3.0
SKEW = EFFECTS["sensor_skew"].params[0]
BACKLASH = EFFECTS["backlash"].params[0]
# The play's regression (``engaged_gear``) takes the samples where the gear torque exceeds this
# share of its amplitude (teeth in contact), and offers its width as a start where it is this
# many times the catalogue's.
ENGAGED = 0.3
PLAY_START = 2.0


@dataclass(frozen=True)
class Estimate:
    """Orders and parameter estimates of one recording (SI units; None: not estimable)."""

    force: float
    speed: float
    values: dict[str, float] = field(default_factory=dict)  # catalogue parameter name -> estimate
    resonance: float | None = None  # [Hz] of the gear, where one is visible
    theta_offset: float = 0.0  # [rad] the link encoder's zero against the motor's (``encoder_offset``)
    # A play's width and the stiffness beyond it (``engaged_gear``), where the deflection shows
    # a dead zone wider than the catalogue's start: a second start for the backlash's screen.
    play: dict[str, float] = field(default_factory=dict)

    @property
    def position(self) -> float:
        return self.speed * 1.0

    @property
    def scales(self) -> dict[str, float]:
        """Each order relative to the catalogue's, rounded to its decade: the factor every
        catalogue value of that dimension is scaled by (``Param.for_plant``)."""
        amp = {"force": self.force, "speed": self.speed, "position": self.position}
        return {k: 10.0 ** round(math.log10(amp[k] / CATALOGUE_ORDERS[k])) for k in CATALOGUE_ORDERS}

    def v_eps(self, timestep: float, default: float, slope_step: float = SLOPE_STEP) -> float:
        """Friction sign regularisation [speed] for a model of this recording: ``default`` unless
        the estimated Coulomb slope Fc / (v_eps J) would be stiffer than ``slope_step`` / timestep
        (a light motor with strong friction is explicitly unstable at its plant's shipped v_eps)."""
        fc, j = self.values.get("coulomb_friction.fc"), self.values.get("inertia.motor")
        if fc is None or j is None:
            return default
        return max(default, fc * timestep / (slope_step * j))

    def param(self, p: Param) -> Param:
        """``p`` (already scaled) started at its estimate, bounds DECADES either side; a
        ``Param.scale_free`` one keeps its range, started at an estimate inside it."""
        v = self.values.get(p.name)
        if p.scale_free:
            return dataclasses.replace(p, initial=v) if v is not None and p.lo <= v <= p.hi else p
        if v is None or not p.log or not v > 0:
            if v is not None and not p.log:  # a signed parameter: its estimate inside the range
                span = max(abs(p.lo), abs(p.hi), 2.0 * abs(v))
                return dataclasses.replace(p, initial=v, lo=min(p.lo, -span), hi=max(p.hi, span))
            return p
        return dataclasses.replace(p, initial=v, lo=v * 10.0 ** -DECADES, hi=v * 10.0 ** DECADES)


def amplitude(x: np.ndarray) -> float:
    """Robust amplitude: the AMPLITUDE_PERCENTILE of |x - median x| (0 for a constant)."""
    x = np.asarray(x, float)
    return float(np.percentile(np.abs(x - np.median(x)), AMPLITUDE_PERCENTILE))


def estimate(measured, arm=None) -> Estimate:
    """The recording's orders and regression estimates (module doc).

    ``measured``: a ``windows.Measured`` (theta None for a direct drive). ``arm``: the nominal
    ``ArmSpec``, whose link is started from the recording where it is of another size (and
    whose inertias a recording without the gear torque splits its rigid inertia by).
    """
    m = measured
    # One zero-phase low-pass for every signal, derivatives after it: the filter commutes with
    # the linear terms of each regression, so they hold between the filtered signals exactly.
    # A slow recording keeps a cutoff below its Nyquist frequency.
    cutoff = min(CUTOFF, CUTOFF_NYQUIST * m.rate / 2.0)
    b, a_ = butter(4, cutoff * 2.0 / m.rate)
    if len(m.q) <= 3 * len(b):  # filtfilt's padding each side
        raise ValueError(f"{len(m.q)} samples are too few to estimate the joint from (at least {3 * len(b) + 1}): "
                         "record longer")
    smooth = lambda x: filtfilt(b, a_, np.asarray(x, float))  # noqa: E731
    rate = lambda x: np.gradient(x, 1.0 / m.rate)  # noqa: E731
    v = rate(smooth(m.q))
    a = rate(v)
    # A held sample acts over the period after it: about a sample instant, the mean of it and the
    # one before (``sim.held_controls``) is what the motion there answers to.
    u = held_controls(m.u, 1, m.u[0])
    guard = int(round(m.rate / cutoff))  # the low-pass's reach: one period of its cutoff
    force = _positive(amplitude(m.u), 1.0)
    speed = _positive(amplitude(v), 1.0)
    values: dict[str, float] = {}
    geared = m.theta is not None
    resonance = None
    if geared:
        theta, delta = smooth(m.theta), smooth(m.delta)
        w = rate(theta)
    if not geared:
        values.update(_motor_regression(smooth(u), v, a, speed, guard))
    elif m.tau is not None:
        tau = smooth(m.tau)
        values.update(_motor_regression(smooth(u) - tau / m.gear_ratio, v, a, speed, guard))
        values.update(_stiffness_regression(delta, rate(delta), tau))
        if arm is not None:
            values.update(_link_start(arm, tau, theta, w, rate(w), guard))
    else:
        # No gear torque: the rigid joint's equation, its inertia J_m + J_l / N^2, the link's
        # gravity torque as two more columns (its zero angle unknown), taken about the mean
        # angle: over a small swing cos(theta) is a constant, which the offset's column is.
        swing = m.theta - np.mean(m.theta)
        gravity = np.column_stack([np.sin(swing), np.cos(swing) - 1.0])
        values.update(_motor_regression(smooth(u), v, a, speed, guard, gravity))
        j_rigid = values.pop("inertia.motor", None)
        link_inertia = None
        if j_rigid is not None and arm is not None:
            split, link_inertia = _rigid_split(j_rigid, m.gear_ratio, arm)
            values.update(split)
        resonance = _resonance(m.u, m.delta, m.rate)
        if resonance is not None and link_inertia is not None:
            j_red = 1.0 / (1.0 / link_inertia + 1.0 / (values["inertia.motor"] * m.gear_ratio ** 2))
            values["linear_stiffness.k1"] = j_red * (2.0 * math.pi * resonance) ** 2
        elif link_inertia is not None and link_inertia != arm.link_inertia:
            # No resonance in view: the gear starts as stiff, for the link's inertia, as the
            # nominal's is for its own (the same locked-link frequency).
            values["linear_stiffness.k1"] = STIFFNESS.initial * link_inertia / arm.link_inertia
    offset, play = 0.0, {}
    if geared and (m.tau is not None or "inertia.motor" in values):
        if m.tau is not None:
            torque, where = tau, slice(None)
        else:  # what the input leaves past the rotor's inertia, where the motor slides (the friction's
            # side is not known: taken as the gear's, as a robot joint's mostly is)
            torque = m.gear_ratio * (smooth(u) + values["input_offset.offset"] - values["inertia.motor"] * a)
            where = (np.abs(v) > MOVING_SHARE * speed) & ~near_reversal(v, guard)
        delta_rate = rate(delta)[where]
        values.update(_encoder_lag(delta[where], torque[where], w[where], delta_rate))
        if "linear_stiffness.k1" in values:
            offset = encoder_offset(delta[where], torque[where], values["linear_stiffness.k1"])
        play = engaged_gear(delta[where], delta_rate, torque[where])
    return Estimate(force, speed, values, resonance, offset, play)


def _encoder_lag(delta: np.ndarray, torque: np.ndarray, link_rate: np.ndarray, delta_rate: np.ndarray
                 ) -> dict[str, float]:
    """Where the link encoder reads late by ``lag``, the measured deflection carries lag theta'
    beside the gear's (T - D delta') / k: ``sensor_skew.lag`` from delta = c + lag theta' -
    (D / k) delta' + T / k (least squares, k and D free), where it lies in the skew's range. The
    damper's column keeps a gear that lags its deflection (a damper, a hysteresis) out of it. A start
    value only: friction on the rotor, which the gear does not carry, moves T by a term in theta'
    too."""
    cols = np.column_stack([np.ones_like(delta), link_rate, delta_rate, torque])
    lag = float(_least_squares(cols, delta)[1])
    return {"sensor_skew.lag": lag} if abs(lag) < SKEW.hi else {}


def engaged_gear(delta: np.ndarray, delta_rate: np.ndarray, torque: np.ndarray) -> dict[str, float]:
    """``backlash.width`` and ``linear_stiffness.k1`` from delta = c + T/k + (b/2) sgn(T) - (D/k)
    delta' on the samples where the gear carries ENGAGED of its torque amplitude: teeth in
    contact lie half the play off the spring's line, on the side of the torque. Returned only
    with a positive k and a width above PLAY_START times the catalogue's start (a gear without
    play, or a hysteretic one, gives a small or negative width)."""
    on = np.abs(torque) > ENGAGED * amplitude(torque)
    if on.sum() < 10:
        return {}
    cols = np.column_stack([np.ones_like(delta), torque, np.sign(torque), delta_rate])[on]
    _, compliance, half, _ = _least_squares(cols, delta[on])
    width = 2.0 * float(half)
    if not (compliance > 0 and width > PLAY_START * BACKLASH.initial):
        return {}
    return {BACKLASH.name: width, STIFFNESS.name: 1.0 / float(compliance)}


def encoder_offset(delta: np.ndarray, torque: np.ndarray, k: float) -> float:
    """[rad] The deflection q/N - theta at zero gear torque, median(delta - T/k), where the torque
    it would take, k |delta_0|, exceeds OFFSET_TORQUES times every torque the gear carries in the
    recording (its robust amplitude): no deflection then, but two encoders counting from
    different zeros. 0 otherwise."""
    if len(delta) < 10:
        return 0.0
    offset = float(np.median(delta - torque / k))
    return offset if k * abs(offset) > OFFSET_TORQUES * amplitude(torque) else 0.0


def _link_start(arm, tau: np.ndarray, theta: np.ndarray, w: np.ndarray, a: np.ndarray, guard: int) -> dict[str, float]:
    """The link's tip mass, gravity and bearing friction from tau = J_L a + G sin(theta) +
    Fl sgn(w) + dl w + c, on the samples where the link moves clearly; returned only where the
    link's inertia is a decade or more off the nominal arm's (``LINK_DECADE``), so a link of the
    nominal's size starts from the catalogue as before, and where that equation holds
    (``LINK_EXPLAINED``). A hub-inertia link (no tip mass) and a fit that finds no positive
    inertia give nothing."""
    if not arm.tip_mass > 0:
        return {}
    speed = amplitude(w)
    moving = (np.abs(w) > MOVING_SHARE * speed) & ~near_reversal(w, guard)
    if moving.sum() < 10 or not speed > 0:
        return {}
    cols = np.column_stack([a, np.sin(theta), np.sign(w), w, np.ones_like(w)])[moving]
    coef = _least_squares(cols, tau[moving])
    j_link, moment, fl, dl, _ = (float(x) for x in coef)
    if not j_link > 0 or abs(math.log10(j_link / arm.link_inertia)) < LINK_DECADE:
        return {}
    if _explained(cols, tau[moving], coef) < LINK_EXPLAINED:
        return {}
    tip = _tip_mass(arm, j_link)
    if tip is None:
        return {}
    out = {"mass.tip": tip}
    if moment > 0:
        out["gravity.g"] = moment / (arm.rod_mass * arm.rod_length / 2 + tip * arm.rod_length)
    out.update({k: v for k, v in (("load_friction.fc", fl), ("load_friction.viscous", dl)) if v > 0})
    return out


def _tip_mass(arm, j_link: float) -> float | None:
    """The tip mass that gives the nominal arm the link inertia ``j_link`` (None: below the
    hub and rod alone)."""
    length = arm.rod_length
    tip = (j_link - arm.hub_inertia - arm.rod_mass * length ** 2 / 3) / length ** 2
    return tip if tip > 0 else None


def _rigid_split(j_rigid: float, gear_ratio: float, arm) -> tuple[dict[str, float], float]:
    """The motor and link inertias of a joint seen only as rigid, ``j_rigid = J_m + J_l / N^2``.

    Below the gear's resonance the two sides move as one, so the recording fixes the sum only.
    Where the sum is within ``LINK_DECADE`` of the nominal arm's, the nominal link stays and the
    motor takes the rest. Otherwise the nominal split means nothing at this size, and both start
    at the matched split J_l = J_m N^2 (the inertia match gear ratios are chosen for); the fit
    moves both. Returns (``inertia.motor`` and the link's parameter where the link is started
    from here, the link's inertia).
    """
    reflected = arm.link_inertia / gear_ratio ** 2
    if abs(math.log10(j_rigid / (arm.motor_inertia + reflected))) < LINK_DECADE and j_rigid > reflected:
        return {"inertia.motor": j_rigid - reflected}, arm.link_inertia
    j_link = 0.5 * j_rigid * gear_ratio ** 2
    out = {"inertia.motor": 0.5 * j_rigid}
    if arm.link_parameter == "mass.tip":
        tip = _tip_mass(arm, j_link)
        if tip is not None:
            out["mass.tip"] = tip
    elif j_link > arm.link_inertia - arm.hub_inertia:
        out["inertia.link"] = j_link - (arm.link_inertia - arm.hub_inertia)
    return out, j_link


def _explained(cols: np.ndarray, y: np.ndarray, coef: np.ndarray) -> float:
    """The share of y's variance the regression y = cols @ coef explains."""
    return 1.0 - float(np.var(y - cols @ coef)) / max(float(np.var(y)), np.finfo(float).tiny)


def _least_squares(cols: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The coefficients of y = cols @ c (least squares), each column scaled to unit norm for the
    solve: the regressions' parameters (an inertia, a friction level, a stiffness) differ by
    decades."""
    norms = np.linalg.norm(cols, axis=0)
    norms[norms == 0] = 1.0
    return np.linalg.lstsq(cols / norms, y, rcond=None)[0] / norms


def _positive(x: float, fallback: float) -> float:
    return x if x > 0 and math.isfinite(x) else fallback


def _motor_regression(y: np.ndarray, v: np.ndarray, a: np.ndarray, speed: float, guard: int,
                      extra: np.ndarray | None = None) -> dict[str, float]:
    """J, Fc, d and the input offset from y = J a + Fc sgn(v) + d v + c (+ ``extra`` columns)
    on the moving samples at least ``guard`` samples from a reversal (the low-pass smears the
    friction's jump over that many); only physically meaningful (positive) magnitudes are
    returned."""
    moving = (np.abs(v) > MOVING_SHARE * speed) & ~near_reversal(v, guard)
    if moving.sum() < 10:
        return {}
    cols = np.column_stack([a, np.sign(v), v, np.ones_like(v), *([] if extra is None else [extra])])[moving]
    coef = _least_squares(cols, y[moving])
    j, fc, d, c = (float(x) for x in coef[:4])
    out = {"input_offset.offset": -c}
    for name, value in (("inertia.motor", j), ("coulomb_friction.fc", fc), ("viscous_friction.sigma", d)):
        if value > 0:
            out[name] = value
    return out


def near_reversal(v: np.ndarray, guard: int) -> np.ndarray:
    """Samples within ``guard`` of a sign change of v."""
    flips = np.flatnonzero(np.diff(np.sign(v)) != 0)
    hit = np.zeros(len(v) + 1, int)
    np.add.at(hit, np.clip(flips - guard, 0, len(v)), 1)
    np.add.at(hit, np.clip(flips + guard + 2, 0, len(v)), -1)
    return np.cumsum(hit)[:-1] > 0


def _stiffness_regression(delta: np.ndarray, delta_rate: np.ndarray, tau: np.ndarray) -> dict[str, float]:
    """k from tau = k delta + D delta' + c (least squares)."""
    cols = np.column_stack([delta, delta_rate, np.ones_like(delta)])
    k = float(_least_squares(cols, tau)[0])
    return {"linear_stiffness.k1": k} if k > 0 else {}


def _resonance(u: np.ndarray, delta: np.ndarray, rate: float) -> float | None:
    """Frequency [Hz] of the peak of |H| = |P_u,delta / P_uu| where it stands PEAK_RATIO above
    the response's median (between 1 Hz and a quarter of the rate, where u has power), else None."""
    n = min(len(u), int(4 * rate))
    f, puu = welch(u, fs=rate, nperseg=n)
    _, pud = csd(u, delta, fs=rate, nperseg=n)
    band = (f >= 1.0) & (f <= rate / 4) & (puu > puu.max() * EXCITED)
    if band.sum() < 5:
        return None
    h = np.abs(pud[band]) / puu[band]
    i = int(np.argmax(h))
    return float(f[band][i]) if h[i] > PEAK_RATIO * np.median(h) else None
