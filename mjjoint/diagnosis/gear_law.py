"""The gear's own law along the measured deflection: what a gear effect must explain.

With encoders on both sides of the gear and a torque sensor at its output, the gear's law
T(delta, delta', history) is measured without simulating anything: the recorded torque against
the recorded deflection. An effect at the gear (``Effect.site`` "gear") changes that law and
nothing else, so if it is in the joint, the model with it, its values as fitted, reproduces the
recorded torque from the recorded deflection better than the model without it. A gear effect
whose simulated gain comes from standing in for physics elsewhere (a rod's damping taken up as
the gear's hysteresis) fits the measured law worse, and is refused (``loop.acceptance``); and
between gear effects the law decides which one the gear has (``loop._by_gear_law``).
"""
from __future__ import annotations

import numpy as np

from ..coupling.kernels import hysteresis_history
from ..coupling.layout import pack
from ..identify.structure import Structure
from ..identify.windows import Predictor


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
