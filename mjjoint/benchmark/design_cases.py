"""Rival pairs a recording cannot separate, with truths drawn on either side (``mjjoint design``).

For each pair, a truth is the concealed-effect base (``cases.make_case("none", seed)``: every
base parameter drawn) plus one rival's effect, drawn from a documented range, and an
*original* open-loop programme under which the two explanations tie:

* ``offset_asymmetry`` (input_offset vs friction_asymmetry): the motor turns one way only
  (a torque above what lifts the link over the top, with a ripple): a constant torque and a
  direction-dependent friction level then act alike;
* ``backlash_hysteresis`` (backlash vs transmission_hysteresis): a small slow torque sine
  (0.01-0.015 N m, a deflection of ~2e-4 rad) inside the hysteresis' elastic range, with a
  play of one to three encoder counts (5e-6 to 1.5e-5 rad): a play comparable to the
  deflection shows on that recording (2e-4 to 6e-4 rad: 0 of 6 draws tied, 2e-5 to 6e-5 rad:
  0 of 6 within 5 %), so the pair is only in question when the play is this small;
* ``viscous_offset`` (viscous_asymmetry vs input_offset): one-way rotation at nearly one
  speed, where sigma r |w| is a constant torque.

``run_case`` fits both rivals to the truth's original recording (as ``mjjoint design`` does),
designs the experiment, records it from the truth (lab sensors) and decides.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..design import Limits, Rival, SearchOptions, decide, design
from ..design.limits import usage, violations
from ..design.record import logged, record
from ..design.response import RivalModel
from ..rehearse import Controller
from ..identify.fit import fit
from ..identify.structure import Structure
from ..identify.windows import Measured, Predictor
from ..rehearse.sensors import Sensors
from .cases import make_case

RATE = 1000.0


def _sign(r: np.random.Generator) -> float:
    return float(r.choice([-1.0, 1.0]))


# effect -> sampler of its truth values (given the base's drawn Coulomb level)
TRUTHS = {
    "input_offset": lambda r, fc: {"input_offset.offset": _sign(r) * fc * r.uniform(0.3, 0.6)},
    "friction_asymmetry": lambda r, fc: {"friction_asymmetry.ratio": _sign(r) * r.uniform(0.3, 0.6)},
    "viscous_asymmetry": lambda r, fc: {"viscous_asymmetry.ratio": _sign(r) * r.uniform(0.3, 0.6)},
    "backlash": lambda r, fc: {"backlash.width": r.uniform(5e-6, 1.5e-5)},
    "transmission_hysteresis": lambda r, fc: {"transmission_hysteresis.mu": r.uniform(0.3, 0.6),
                                              "transmission_hysteresis.x_u": r.uniform(1e-3, 3e-3)},
}


def _one_way(t: np.ndarray, r: np.random.Generator, ripple: float) -> np.ndarray:
    return _sign(r) * (r.uniform(0.15, 0.18) + ripple * np.sin(2 * np.pi * r.uniform(1.0, 2.0) * t))


# pair -> (rival effects, original programme u(t, rng))
PAIRS = {
    "offset_asymmetry": (("input_offset", "friction_asymmetry"), lambda t, r: _one_way(t, r, 0.03)),
    "backlash_hysteresis": (("backlash", "transmission_hysteresis"),
                            lambda t, r: r.uniform(0.01, 0.015) * np.sin(2 * np.pi * r.uniform(0.5, 1.0) * t)),
    "viscous_offset": (("viscous_asymmetry", "input_offset"), lambda t, r: _one_way(t, r, 0.005)),
}


@dataclass(frozen=True)
class DesignCase:
    pair: str
    truth_effect: str
    seed: int
    truth: Structure
    base: Structure
    original: np.ndarray   # torque samples of the original (tied) programme


def make_design_case(pair: str, side: int, seed: int, duration: float = 8.0) -> DesignCase:
    """Truth with rival ``side`` (0 or 1) of ``pair``, and its original programme."""
    if pair not in PAIRS:
        raise ValueError(f"unknown pair {pair!r} (allowed: {', '.join(PAIRS)})")
    effects, programme = PAIRS[pair]
    effect = effects[side]
    base = make_case("none", seed).truth
    r = np.random.default_rng(2000 + 7 * seed + side)
    truth = base.with_effect(effect, TRUTHS[effect](r, base.values["coulomb_friction.fc"]))
    t = np.arange(int(round(duration * RATE))) / RATE
    return DesignCase(pair, effect, seed, truth, base, programme(t, r))


def fit_rivals(case: DesignCase, max_iter: int = 15) -> tuple[tuple[Rival, Rival], dict]:
    """Both rivals fitted to the truth's original recording (as ``mjjoint design`` does), and
    the case's record so far (pair, truth, seed, both rivals' held-out costs: the tie)."""
    old = record(case.truth, case.original, RATE, Sensors(seed=case.seed))
    predictor = Predictor(Measured.from_recording(old, case.truth.gear_ratio))
    effects = PAIRS[case.pair][0]
    fits = [fit(predictor, case.base.with_effect(e), max_iter=max_iter) for e in effects]
    rivals = tuple(Rival(e, f.structure, f.intervals) for e, f in zip(effects, fits))
    return rivals, {"pair": case.pair, "truth": case.truth_effect, "seed": case.seed,
                    "original_heldout": {e: f.cost_test for e, f in zip(effects, fits)}}


def tie(found: dict) -> float:
    """How much higher the worse rival's held-out cost on the original recording is (0.05: 5 %)."""
    costs = list(found["original_heldout"].values())
    return max(costs) / min(costs) - 1


def run_case(case: DesignCase, limits: Limits, options: SearchOptions, max_iter: int = 15,
             loop: Controller | None = None, fitted: tuple | None = None) -> dict:
    """Fit both rivals to the original recording (or take ``fitted``, ``fit_rivals``' result),
    design (open loop, or with ``loop`` a reference for that controller), record the design
    from the truth, decide."""
    start = time.perf_counter()
    rivals, found = fit_rivals(case, max_iter) if fitted is None else fitted
    try:
        d = design(rivals, None, limits, options, loop=loop)
    except ValueError as exc:  # no input within the limits: a failed case, not a crash
        return {**found, "family": None, "error": str(exc), "correct": False, "decisive": False,
                "seconds": time.perf_counter() - start}
    truth_model = RivalModel(Rival(case.truth_effect, case.truth), RATE, 0, loop=d.loop)
    truth_run = truth_model.run(d.best.u)
    new = logged(truth_run, Sensors(seed=case.seed + 100))
    decision = decide(rivals, new, d.noise, max_iter=max_iter)
    # The limits on the truth's own run of the designed input (the rivals' were checked in design).
    return {**found, "family": d.best.family, "D": d.best.score, "D_heldout": d.heldout_discrimination,
            "D_chirp": d.reference.score, "unbeaten": d.unbeaten,
            "chirp_usage": d.reference.usage, "chirp_feasible": d.reference.feasible, "usage": d.best.usage,
            "truth_violations": violations(truth_run, limits, "truth"), "truth_usage": usage(truth_run, limits),
            "loop": d.loop is not None,
            "rehearsed": d.rehearsed_ratio,
            # the rehearsal whose recording came from the rival with the truth's effect
            "rehearsed_truth_side": None if d.best.rehearsal is None else
            d.best.rehearsal.evidence[[r.effect for r in rivals].index(case.truth_effect)],
            "llr": decision.llr if decision.winner == case.truth_effect else -decision.llr,
            "winner": decision.winner, "correct": decision.winner == case.truth_effect,
            "decisive": decision.decisive, "p": decision.p_value, "gap": decision.relative_gap,
            "seconds": time.perf_counter() - start}
