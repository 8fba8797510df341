"""Friction-map mode: the catalogued friction effects fitted to a friction log (t, q, tau).

A friction rig, or a cobot joint's friction log, records the friction torque tau against a
prescribed motion q. No inertia, stiffness or input enters: each friction effect of the
catalogue (``effects.EFFECTS``) builds the motor-friction term the simulator runs, which is
driven here by the measured velocity (the Savitzky-Golay derivative the windows' start
velocities use) and compared with tau sample by sample. The static map is the plugin's own
kernel (``stribeck.static_friction``); 2SEP runs its states along the measured velocity with the
plugin's step (``kernels.friction_history``) and gives F = z1 + B|w|z2 (``twosep.twosep_force``),
so pre-sliding and the frictional lag are fitted too.

The effects are named as ``diagnose`` names them: from the base (Coulomb and viscous), the
candidate that lowers the held-out RMS most is added while it lowers it by ``min_gain`` or
more. Held out: a seeded random quarter of blocks of ``BLOCK`` s, so no effect is named for
fitting the very samples it is judged on.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from ..assets import ArmSpec
from ..coupling.kernels import friction_history
from ..coupling.layout import NSTATE, Z1, Z2, pack
from ..joint import JointParams
from ..physics.jit import kernel
from ..physics.stribeck import StaticFriction, static_friction
from ..physics.twosep import TwoSEP, twosep_force
from ..recordings.consistency import motion_problem
from .effects import EFFECTS, Param, check_effects
from .windows import velocity

# A friction log is one joint's friction against its own motion: the friction effects a direct
# drive can have (not those of a gear's transmitted torque, which the log does not hold).
FRICTION_EFFECTS = tuple(e.name for e in EFFECTS.values() if e.term == "friction" and e.direct_drive)
BASE = ("coulomb_friction", "viscous_friction")
BLOCK = 0.25  # [s] held-out blocks: long against the friction's memory (2SEP's lag, ms)
HOLDOUT = 0.25
MIN_BLOCKS = 8  # blocks a log must hold: two held out, six fitted
# The static map's sign regularisation, as a share of the log's typical speed. The plugin's
# v_eps (1 rad/s) is set by the explicit integrator's stability, which a map evaluated on a
# measured velocity does not need; a wide one smooths the jump at reversals, and on a
# Coulomb-and-viscous log a Stribeck term with a tiny vs was then named to undo it
# (SIGN_SHARE 1e-3: held-out RMS 2x the noise, Stribeck named).
SIGN_SHARE = 1e-6
MAX_EVALUATIONS = 200


@dataclass(frozen=True)
class FrictionLog:
    """Friction torque against a measured motion, one or more segments (separate runs)."""

    segments: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]  # (t, q, tau) per run

    @property
    def rate(self) -> float:
        t = self.segments[0][0]
        return (len(t) - 1) / float(t[-1] - t[0])

    @property
    def tau(self) -> np.ndarray:
        return np.concatenate([tau for _, _, tau in self.segments])

    @property
    def w(self) -> np.ndarray:
        """The measured velocity, each segment differentiated on its own."""
        return np.concatenate([velocity(q, 1.0 / self.rate) for _, q, _ in self.segments])


@dataclass(frozen=True)
class _Scale:
    """The friction log's orders of torque and speed, for the catalogue's parameter ranges
    (``Param.for_plant``: the catalogue's ranges are the lab arm's motor side)."""

    force: float
    speed: float

    @property
    def scales(self) -> dict[str, float]:
        return {"force": self.force, "speed": self.speed, "position": 1.0}

    def unit(self, unit: str) -> str:
        return unit


def friction_term(effects, values: dict[str, float], v_eps: float) -> StaticFriction | TwoSEP:
    """The simulator's motor-friction term that these effects and values build."""
    model: Any = (ArmSpec(), JointParams(friction=None))
    for name in check_effects(effects, FRICTION_EFFECTS):
        model = EFFECTS[name].apply(model, values)
    f = model[1].friction
    return dataclasses.replace(f, v_eps=v_eps) if isinstance(f, StaticFriction) else f


@kernel
def _static_trace(w, fc, fs, vs, shape, sigma, asym, v_eps, sigma_asym):
    out = np.empty(w.shape[0])
    for i in range(w.shape[0]):
        out[i] = static_friction(w[i], fc, fs, vs, shape, sigma, asym, v_eps, sigma_asym)
    return out


@kernel
def _twosep_trace(states, w, b):
    out = np.empty(w.shape[0])
    for i in range(w.shape[0]):
        out[i] = twosep_force(states[i, Z1], states[i, Z2], w[i], b)
    return out


def friction_trace(f: StaticFriction | TwoSEP, w: np.ndarray, h: float) -> np.ndarray:
    """The torque the friction term gives along the velocity ``w`` (sample period h), from rest."""
    w = np.ascontiguousarray(w, dtype=float)
    if isinstance(f, StaticFriction):
        return _static_trace(w, f.fc, f.fs, f.vs, f.shape, f.sigma, f.asym, f.v_eps, f.sigma_asym)
    blk = pack(dataclasses.replace(JointParams(), friction=f), 0, 0, 0, 0)
    return _twosep_trace(friction_history(blk, w, np.zeros(len(w)), h, np.zeros(NSTATE)), w, f.b)


@dataclass
class MapFit:
    effects: tuple[str, ...]
    values: dict[str, float]
    rms_train: float
    rms_test: float
    rms: float  # over every sample [N m]
    prediction: np.ndarray = field(repr=False)


@dataclass
class FrictionMap:
    """The base fit, the effects named in order (with the held-out RMS each took away), the final fit."""

    base: MapFit
    steps: list[dict]
    final: MapFit
    v_eps: float

    def as_dict(self) -> dict:
        fit = lambda m: {"effects": list(m.effects), "parameters": m.values,  # noqa: E731
                         "rms": m.rms, "rms_train": m.rms_train, "rms_heldout": m.rms_test}
        return {"unit": "N m", "missing": [s["effect"] for s in self.steps], "steps": self.steps,
                "base": fit(self.base), "final": fit(self.final), "sign_regularisation": self.v_eps}


class _Problem:
    """One friction log, its held-out split and the parameter ranges scaled to it."""

    def __init__(self, log: FrictionLog, seed: int):
        self.tau, self.w, self.h = log.tau, log.w, 1.0 / log.rate
        self.bounds = np.cumsum([0, *(len(t) for t, _, _ in log.segments)])
        for _, q, _ in log.segments:
            problem = motion_problem(q)
            if problem is not None:
                raise ValueError(f"friction log: {problem}")
        span = len(self.tau) * self.h
        if span < MIN_BLOCKS * BLOCK:  # a held-out share and a fitted one, each of whole blocks
            raise ValueError(f"friction log: {span:.3g} s holds fewer than {MIN_BLOCKS} blocks of {BLOCK:g} s to fit "
                             "and hold out; log longer")
        moving = np.abs(self.w) > 0
        speed = float(np.median(np.abs(self.w[moving]))) if moving.any() else 1.0
        self.v_eps = SIGN_SHARE * speed
        force = float(np.median(np.abs(self.tau))) or 1.0
        # The catalogue's Coulomb guess (0.05 N m) meets the log's median torque; its Stribeck
        # velocity (0.5 rad/s) the log's median speed.
        self.scale = _Scale(force=force / 0.05, speed=speed / 0.5)
        block = max(1, int(round(BLOCK / self.h)))
        ids = np.arange(len(self.tau)) // block
        rng = np.random.default_rng(seed)
        blocks = np.unique(ids)
        held = rng.permutation(blocks)[: max(1, int(round(HOLDOUT * len(blocks))))]
        self.test = np.isin(ids, held)
        self.initial = self._linear_guess()

    def _linear_guess(self) -> dict[str, float]:
        """Coulomb level and viscous slope by linear least squares where the log slides."""
        sliding = np.abs(self.w) > 10 * self.v_eps
        a = np.column_stack([np.sign(self.w[sliding]), self.w[sliding]])
        (fc, sigma), *_ = np.linalg.lstsq(a, self.tau[sliding], rcond=None)
        return {"coulomb_friction.fc": float(fc), "viscous_friction.sigma": float(sigma)}

    def params(self, effects) -> list[Param]:
        return [p.for_plant(self.scale) for e in effects for p in EFFECTS[e].params]

    def trace(self, effects, values: dict[str, float]) -> np.ndarray:
        f = friction_term(effects, values, self.v_eps)
        # Each run starts from rest: the friction's memory does not carry across runs.
        return np.concatenate([friction_trace(f, self.w[a:b], self.h) for a, b in zip(self.bounds[:-1], self.bounds[1:])])

    def fit(self, effects, start: dict[str, float]) -> MapFit:
        effects = check_effects(effects, FRICTION_EFFECTS)
        params = self.params(effects)
        lo = np.array([p.to_unit(p.lo) for p in params])
        hi = np.array([p.to_unit(p.hi) for p in params])
        x0 = np.array([p.to_unit(min(max(start.get(p.name, p.initial), p.lo), p.hi)) for p in params])
        x0 = np.clip(x0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
        train = ~self.test

        def values(x):
            return {p.name: p.from_unit(v) for p, v in zip(params, x)}

        def residual(x):
            return (self.trace(effects, values(x)) - self.tau)[train]

        x = least_squares(residual, x0, bounds=(lo, hi), method="trf", x_scale="jac",
                          max_nfev=MAX_EVALUATIONS).x
        vals = values(x)
        pred = self.trace(effects, vals)
        err = pred - self.tau
        rms = lambda e: float(np.sqrt(np.mean(e ** 2)))  # noqa: E731
        return MapFit(effects, vals, rms(err[train]), rms(err[self.test]), rms(err), pred)


def fit_friction_map(log: FrictionLog, candidates=None, min_gain: float = 0.05, seed: int = 0,
                     base=BASE) -> FrictionMap:
    """Fit the base, then name the candidates (default: every friction effect) that lower the
    held-out RMS by ``min_gain`` (relative) or more, the best first."""
    if not 0 < min_gain < 1:
        raise ValueError(f"min_gain={min_gain!r} must lie in (0, 1)")
    problem = _Problem(log, seed)
    current = problem.fit(base, problem.initial)
    first = current
    pool = [c for c in (candidates or FRICTION_EFFECTS) if c not in current.effects]
    steps = []
    while pool:
        tries = []
        for c in pool:
            try:
                effects = check_effects((*current.effects, c), FRICTION_EFFECTS)
            except ValueError:
                continue  # its prerequisite is not in the model (yet)
            tries.append(problem.fit(effects, current.values))
        if not tries:
            break
        best = min(tries, key=lambda m: m.rms_test)
        gain = (current.rms_test - best.rms_test) / current.rms_test
        if gain < min_gain:
            break
        added = next(e for e in best.effects if e not in current.effects)
        steps.append({"effect": added, "rms_heldout_before": current.rms_test, "rms_heldout_after": best.rms_test,
                      "gain": gain})
        current = best
        pool.remove(added)
    return FrictionMap(first, steps, current, problem.v_eps)
