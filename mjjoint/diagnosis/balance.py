"""The rotor's torque balance along a recording: where a torque on the motor shows as a function
of the motor's own angle.

A torque on the rotor that depends on its angle (cogging, a friction level that varies over a
revolution) reaches the output signals only through the joint's dynamics: filtered by its
modes, the prediction residual of the deflection or the gear torque shows it at the gear's
resonance, not as a function of q. Where the gear torque is recorded, the rotor's balance shows
it directly: the input less what a rigid rotor with a static friction curve, loaded by the
recorded gear torque and driven through a lag, takes,

    r = u - (a q'' + b sgn(q') + c q' + d + e tau + f u' + sum_i s_i sgn(q') exp(-|q'| / v_i)),

each coefficient fitted by least squares (so neither u's unit nor the gear ratio need be known;
the v_i are locate's Stribeck widths, u' stands for an input that acts late). Each term the
rotor can have whatever its angle takes out of r what would otherwise follow the motion and so
project onto some period of q. A resting rotor's friction is whatever holds it, no law of the
motion: the rests are left out (a caller's ``moving`` mask), or each rest's holding level, at the
rest's angle, passes for a friction level periodic in q.

Only the conditions of an angle-periodic torque are scored on it, at real periods that repeat
at least PERIODS times over the recorded travel: the friction's other structure in r is the
model's business, judged on the output signals, and a slow wander of r over the record (a lag's
error follows the excitation) is no period.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .locate import (STRIBECK_SPEEDS, SignalLocation, condition_scores, friction_periodic, nrmse, real_periodic,
                     residual_windows)

SIGNAL = "motor_balance"  # its name among a location's signals
PERIODS = 4               # a period claimed repeats at least this often over the motor's travel
# What the rotor's terms leave of the friction's dynamics still follows the motion, and so some
# period of q explains a few per cent of r in any recording; a period claimed explains a tenth.
MIN_EFFECT = 0.1
MAX_STEPS = 2000          # real periods scanned at most (a longer travel is scanned coarser)


def motor_balance(conditions: Mapping[str, np.ndarray], moving: np.ndarray | None = None) -> np.ndarray | None:
    """The residual r of the rotor's balance (module doc) from ``features.operating_conditions``'
    arrays, fitted and kept where ``moving`` (default: everywhere), zero elsewhere; None without a
    recorded gear torque."""
    if "tau" not in conditions:
        return None
    moving = np.ones(len(conditions["qd"]), dtype=bool) if moving is None else np.asarray(moving, dtype=bool)
    qd, u, sign = conditions["qd"], conditions["u"], np.sign(conditions["qd"])
    speed = float(np.quantile(np.abs(qd), 0.95))
    stribeck = [sign * np.exp(-np.abs(qd) / (f * speed)) for f in STRIBECK_SPEEDS] if speed > 0 else []
    cols = np.column_stack([conditions["qdd"], sign, qd, np.ones_like(qd), conditions["tau"], conditions["ud"],
                            *stribeck])
    coef, *_ = np.linalg.lstsq(cols[moving], u[moving], rcond=None)
    return np.where(moving, u - cols @ coef, 0.0)


def balance_location(t: np.ndarray, conditions: Mapping[str, np.ndarray], *, moving: np.ndarray | None = None,
                     n_windows: int = 3, min_width: float = 0.1, n_permutations: int = 19,
                     min_effect: float = MIN_EFFECT, seed: int = 0) -> SignalLocation | None:
    """``locate``'s account of one signal for the rotor's balance (``motor_balance``, where
    ``moving``): its residual windows and the angle-periodic conditions' scores, on the same scale
    and noise threshold; None without a recorded gear torque or a varying input."""
    r = motor_balance(conditions, moving)
    u = np.asarray(conditions.get("u", ()), dtype=float)
    if r is None or not np.any(r) or not np.std(u) > 0:
        return None
    q = conditions["q"]
    built = (real_periodic("periodic_q", "q", q, PERIODS, MAX_STEPS), friction_periodic(q, conditions["qd"], PERIODS))
    # t (u beside it, as the scores want both) sets the nulls' blocks: sample-by-sample
    # permutations of a smooth residual would take any slow wander for structure.
    scores = condition_scores(r, conditions, t=t, measured=u, n_permutations=n_permutations, min_effect=min_effect,
                              seed=seed, built=built)
    return SignalLocation(SIGNAL, nrmse(u, u - r), tuple(residual_windows(t, r, n_windows, min_width)),
                          tuple(scores))
