"""The gear's own law along the measured deflection: what a gear effect must explain.

With encoders on both sides of the gear and a torque sensor at its output, the gear's law
T(delta, delta', history) is measured without simulating anything: the recorded torque against
the recorded deflection. An effect at the gear (``Effect.site`` "gear") changes that law and
nothing else, so if it is in the joint, the model with it, its values as fitted, reproduces the
recorded torque from the recorded deflection better than the model without it. A gear effect
whose simulated gain comes from standing in for physics elsewhere (a rod's damping taken up as
the gear's hysteresis) fits the measured law worse, and is refused (``loop.acceptance``); and
between gear effects the law decides which one the gear has (``loop._by_gear_law``).

The same pair of columns carries a sign no model is needed to read: a passive gear takes energy
from the motion, so the recorded torque's work along the recorded deflection, the spring's
stored share taken off, is positive over any stretch (``law_energy``). Where it is negative, the
recorded torque runs behind the recorded deflection: a torque cell's filter or a clock skew
between the sensors, which no physics of the joint produces.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import wilcoxon

from ..coupling.kernels import hysteresis_history
from ..coupling.layout import pack
from ..identify.structure import Structure
from ..identify.windows import Measured, Predictor

# The recording's sign (``Effect.evidence``) that the gear law gives energy back.
ENERGY_RETURNED = "energy_returned"
ENERGY_STRETCH = 0.25  # [s] the stretches the work is summed over, tested for their sign
ENERGY_P = 1e-3        # the signed-rank level below which the law is taken to give energy back


def gear_torque(joint, delta: np.ndarray, rate: np.ndarray, at: np.ndarray, segments) -> np.ndarray:
    """The transmission torque of ``joint`` at samples ``at`` along the deflection path ``delta``
    with rate ``rate``; Bouc-Wen's state runs along each recording's path from 0, as the
    windows' histories run it."""
    tr = joint.transmission
    x = np.zeros_like(delta)
    if tr.hysteresis is not None:
        blk = pack(joint, 0, 0, 1, 1)
        x = np.concatenate([hysteresis_history(blk, delta[a:b], 0.0) for a, b in segments])
    return np.array([tr.torque(delta[i], rate[i], x[i]) for i in at.ravel()]).reshape(at.shape)


def law_costs(predictor: Predictor, structure: Structure, windows: np.ndarray) -> np.ndarray:
    """Per window, the mean square of the recorded torque minus the structure's gear torque along
    the recorded deflection, as its sensors report it (a torque sensor's gain)."""
    m = predictor.m
    idx = predictor.starts[windows][:, None] + np.arange(predictor.nwin_samples)[None, :]
    torque = gear_torque(structure.model_params()[1], m.delta_path, m.qd / m.gear_ratio - m.thetad, idx, m.segments)
    seen = structure.measured({"q": m.q[idx], "theta": m.theta[idx], "delta": m.delta[idx], "tau": torque}, m.rate)
    return np.mean((m.tau[idx] - seen["tau"]) ** 2, axis=1)


def law_site(effect) -> str:
    """The site ``law_ratio`` judges an ``Effect`` at: "gear" for an effect at the gear (it
    changes the law and nothing else) and for one of the torque sensor's (``Effect.senses`` tau
    alone: it changes what the recording reports of the law's torque; a late cell puts the
    recorded torque behind the recorded deflection); its own site otherwise."""
    torque_sensor = effect.site == "sensor" and set(effect.senses) <= {"tau"}
    return "gear" if torque_sensor else effect.site


def law_ratio(predictor: Predictor, before: Structure, after: Structure, effect_site: str) -> float | None:
    """The held-out windows' gear-law cost of ``after`` over that of ``before`` (below 1: the
    measured law is fitted better); None where it does not apply: an effect elsewhere than the
    gear, no torque sensor or link encoder, or ``before`` without a gear spring (a rigid gear has
    no law to compare with)."""
    if effect_site != "gear" or "linear_stiffness" not in before.effects:
        return None
    m = predictor.m
    if m.tau is None or m.measured_delta is None:
        return None
    w = predictor.test
    return float(law_costs(predictor, after, w).sum() / law_costs(predictor, before, w).sum())


@dataclass(frozen=True)
class LawEnergy:
    """The work of the recorded gear torque along the recorded deflection (``law_energy``)."""

    damping: float   # [N m s/rad] that work over the integral of the deflection rate squared
    stiffness: float  # [N m/rad] the law's secant stiffness, whose stored energy is taken off
    returned: int    # stretches that gave energy back
    stretches: int
    p: float         # one-sided signed-rank p that the stretches' works are negative

    @property
    def shown(self) -> bool:
        return self.p <= ENERGY_P

    def describe(self) -> str:
        return (f"the recorded gear law gives energy back ({self.returned} of {self.stretches} stretches of "
                f"{ENERGY_STRETCH:g} s, signed-rank p {self.p:.2g}; {self.damping:.3g} N m s/rad of damping "
                f"along the deflection), which no passive gear does: the torque is read late against the "
                f"deflection (a torque cell's filter, a clock skew)")


def law_energy(m: Measured) -> LawEnergy | None:
    """The recorded torque's work along the recorded deflection, per stretch of ENERGY_STRETCH
    within each stacked recording, less what the law's best linear spring stores between the
    stretch's ends; None without a torque sensor and a link encoder or with too few stretches.
    The trapezoidal sum telescopes the spring's work exactly and leaves the encoders'
    quantisation and independent sensor noise without bias."""
    delta = m.measured_delta
    if m.tau is None or delta is None:
        return None
    k, c = np.polyfit(delta, m.tau, 1)
    sign = 1.0 if k >= 0 else -1.0  # a torque column of the opposite sense
    tau, k, c = sign * m.tau, sign * k, sign * c
    n = max(int(round(ENERGY_STRETCH * m.rate)), 2)
    works, rates = [], []
    for a, b in m.segments:
        for s in range(a, b - n + 1, n):
            d, t = delta[s:s + n], tau[s:s + n]
            work = np.sum(0.5 * (t[1:] + t[:-1]) * np.diff(d))
            works.append(work - 0.5 * k * (d[-1] ** 2 - d[0] ** 2) - c * (d[-1] - d[0]))
            rates.append(np.sum(np.diff(d) ** 2) * m.rate)
    works = np.asarray(works)
    if len(works) < 10 or not np.any(works != 0):
        return None
    return LawEnergy(damping=float(works.sum() / sum(rates)), stiffness=float(k), returned=int(np.sum(works < 0)),
                     stretches=len(works), p=float(wilcoxon(works, alternative="less").pvalue))
