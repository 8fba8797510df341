"""Fit a structure's parameters to a recording by windowed prediction error.

The optimiser is MuJoCo's own bounded Levenberg-Marquardt (``mujoco.minimize``), whose
residual is vectorised over parameter vectors: every finite-difference Jacobian is ONE batched
``mujoco.rollout`` of all windows for all perturbed models, spread over the cores. Parameters
are optimised in log coordinates where they span decades. The LM runs first on a seeded
quarter of the windows, then on all of them, and stops when its Gauss-Newton step is a tenth
of the parameters' standard errors, or when a trial step fails within half of one (constants
below). A fit may stop between the two phases (``subset_only``: the diagnosis screens every
candidate so) and be finished later (``finish``) to exactly the whole fit's result; each of the
two is made once per predictor and arguments (``_MEMO``, ``_Partial.finished``). The
Jacobian's columns around a point whose model passed the stability check are not checked
again (``Predictor.predict(assume_stable=True)``). 95 % intervals come from the Jacobian at
the optimum, with the windows as the independent units (``intervals``: a window's residuals
share its start-state error); a parameter whose interval is wider than its value, or that sits
on a bound, is flagged. ``check_intervals`` then tests chosen intervals against the cost itself
(``intervals.profile_intervals``): moved where it is not quadratic over them, or flagged, and
widened by the step's bias where the model's discretisation moves the estimate more than the
noise does (``step_bias``), and by the fit's own bias, the move the same fit makes on the fitted
model's twin of the recording (``twin_bias``).

Robust cost over windows (``robust=True``; the diagnosis's refits and final estimate, docs/diagnosis.md):
the fitted objective is sum_i s log(1 + c_i / s) over the windows' mean squared residuals c_i
(a Cauchy loss on whole windows), with the scale s the median window cost, re-estimated between
LM runs (SCALE_ROUNDS); least squares is its limit s -> inf. Per-window costs are heavy tailed:
a window whose start state is off stays off (20 s torque_ripple case: the windows that begin at
a step of the input, where the centred velocity estimate takes in the acceleration after the
step, ~10 rad/s; the TRUE model's median window cost is 3e-5, six of the 59 training windows
cost 0.018-0.057, 94 % of the sum). Least squares spends the parameters on those few windows
(there: ripple amplitude -8 %, phase 7 deg off, held-out cost 0.00329 against the truth's
0.00248); under the Cauchy loss a window 100x worse than typical counts ~5x, not 100x, and the
fit reaches the truth's held-out cost with its ripple within 1-4 %. Held-out costs, the
acceptance tests and the reported costs stay mean squares.
"""
from __future__ import annotations

import dataclasses
import time
import weakref
from dataclasses import dataclass, field

import numpy as np
from mujoco import minimize

from .effects import EFFECTS
from .intervals import EIG_FLOOR, Optimum, intervals, profile_intervals, residual_variance
from .structure import Structure
from .twin import Twin
from .windows import Predictor

_BAD = 1e3  # residual given to an unstable (NaN) prediction: far worse than any real fit
# Stopping rule. The Gauss-Newton step at the current point, measured in the fit's own
# standard errors (the metric of the covariance s^2 (J^T J)^-1 the intervals come from,
# ``gauss_newton_step_se``): once it is below STEP_SE, no combination of the parameters would
# move by more than 0.1 of its standard error (0.05 of its 95 % half-width), and the Jacobian
# just taken there serves the intervals. The same rule stops a fit that stalls: when the last
# STALL_ITER accepted steps together lowered r'r by less than STEP_SE^2 s^2 (what a 0.1-SE move
# is worth). A relative step of XTOL in the (log-)unit coordinates stays as a backstop (the
# default 1e-8 never fires on these residuals, ~1e4 entries of O(0.01-1)).
STEP_SE = 0.1
STALL_ITER = 2
XTOL = 1e-4
# A trial step that fails to lower r'r once the Gauss-Newton step is within FAIL_SE standard
# errors ends the fit at the last accepted point: all the quadratic model still promises is
# FAIL_SE^2 s^2, and a failure there means the cost is not quadratic at that scale (a model
# that lacks a backlash, or quantised sensors: bench_fit (c) spent 11 trials, each a rollout
# of all windows, raising mu between points whose r'r agreed to 6 digits).
FAIL_SE = 0.5
# Coarse to fine: the first LM phase runs on a seeded COARSE_SHARE of the training windows (at
# least COARSE_MIN, and only if all windows are at least twice as many) until its step is
# within COARSE_SE of the subset's standard errors; far from the optimum a quarter of the
# windows points the same way at a quarter of the rollouts. The second phase starts there on
# all windows and ends on STEP_SE, so the end point is the full fit's.
COARSE_SHARE = 0.25
COARSE_MIN = 8
COARSE_SE = 1.0
# Damping. mujoco.minimize adds mu I to J^T J (log parameters, residuals scaled per signal).
# Each failed trial step costs a rollout of all windows and raises mu by MU_FACTOR: at MuJoCo's
# default 10^0.1 from its 1e-6, a fit with an unmodelled backlash spent 88 trials (66
# rollouts) in one iteration climbing to the mu it needed; from MU_MIN = 1e-3, sqrt(10) takes 2
# trials per decade. (A tenfold factor stalled a drive fit in a narrow valley at 30 % Coulomb
# error, tests/test_drive.py; that fit converges with these settings.) No column scaling
# (x_scale="jac", Marquardt's): it makes mu relative to each column's norm, so a parameter the
# data barely constrain takes one step across its whole range (BAM per-log fits: link inertia
# 1e-5 -> 100 kg m^2, then g to its bound, where the stall rule stopped; tests/test_bam.py,
# slow set); bench_fit (c) needs the same rollouts without it.
MU_MIN = 1e-3
MU_FACTOR = 10.0 ** 0.5
EPS = np.finfo(np.float64).eps ** 0.5  # mujoco.minimize's own finite-difference step
# Robust loss (module doc): its scale s is the median window cost where the LM starts; after a
# run it is re-estimated at the result, and LM runs again from there while s fell more than
# twofold, at most SCALE_ROUNDS runs (a fit from a poor start would otherwise end near least
# squares: drive with three corrupted windows, tests/test_robust_cost.py).
SCALE_ROUNDS = 3
# Restarts (``fit(restarts=...)``): a fit whose training cost is this many times the noise
# floor has not explained the data (a fit of the right structure ends within a few times it);
# random starts spread this many decades (normal std) around the initial values.
FAR_ABOVE = 100.0
RESTART_DECADES = 1.0


@dataclass
class FitResult:
    structure: Structure
    cost_train: float
    cost_test: float
    nrmse_train: dict[str, float]
    nrmse_test: dict[str, float]
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    iterations: int = 0
    rollouts: float = 0.0
    seconds: float = 0.0
    coarse_iterations: int = 0  # of ``iterations``, those on the window subset (COARSE_SHARE)
    coarse_capped: bool = False  # the subset phase stopped at ``max_iter``, not at its step rule
    on_bound: tuple[str, ...] = ()  # fitted parameters on a bound that marks a stand-in (Structure.stand_in_bounds)
    # Per training window (``Predictor.train``), the mean squared normalised residual; and the
    # training windows the fit left out, its model leaving their start open (``Predictor.undetermined``).
    train_costs: np.ndarray | None = field(default=None, repr=False, compare=False)
    left_out: tuple[int, ...] = ()
    starts: int = 1  # fits run from different starting points (``restarts``), the best kept
    robust: bool = False  # fitted under the robust loss over windows (``fit(robust=True)``)
    # The least-squares training cost where a fit without a subset phase started (its first LM
    # objective over all its windows; NaN under the robust loss or after a subset phase, whose
    # own start is ``partial.start_loss``): what a fit started there with fewer parameters free
    # cannot end above (``training_ratio(from_start=True)``).
    start_cost: float = float("nan")
    # Set on a fit stopped after its subset phase (``fit(subset_only=True)``): where ``finish``
    # goes on. Such a result holds the held-out cost and NRMSE only (train: NaN, {}).
    partial: "_Partial | None" = field(default=None, repr=False, compare=False)
    # Where the intervals came from, for their check against the model (``check_intervals``).
    at_optimum: "_AtOptimum | None" = field(default=None, repr=False, compare=False)

    def as_dict(self) -> dict:
        return {"structure": self.structure.describe(), "cost_train": self.cost_train,
                "cost_test": self.cost_test, "nrmse_train": self.nrmse_train, "nrmse_test": self.nrmse_test,
                "intervals_95": {k: list(v) for k, v in self.intervals.items()}, "warnings": self.warnings,
                "iterations": self.iterations, "coarse_iterations": self.coarse_iterations,
                "rollouts": self.rollouts, "seconds": self.seconds, "on_bound": list(self.on_bound),
                "starts": self.starts, "robust": self.robust}


def residual_matrix(pred_fn, structure: Structure, names, windows, predictor: Predictor, seen: dict | None = None,
                    scale: float | None = None):
    """Residual columns for parameter vectors (columns of x); ``pred_fn(structures, windows)``
    gives their predictions, one at a time (``Predictor.predictions``): each is reduced to its
    residual column before the next is made. ``seen`` keeps the predictions of the last
    single-vector call ({"x": x, "pred": ...}). With a loss ``scale`` the residuals are those of
    the Cauchy loss over windows (``robust_residuals``)."""
    def residual(x: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(x.T).T if x.ndim == 1 else x
        structs = [structure.from_vector(x[:, i], names) for i in range(x.shape[1])]
        r, i = None, 0
        for p in pred_fn(structs, windows):  # not enumerate: its cached tuple would hold the last p
            if seen is not None and len(structs) == 1:
                seen.update(x=x[:, 0].copy(), pred=p)
            col = predictor.residuals(p, windows)
            if r is None:
                r = np.empty((len(col), len(structs)))
            r[:, i] = np.where(np.isfinite(col), col, _BAD)
            i += 1
            del p, col  # not held while the next structure is predicted
        return r if scale is None else robust_residuals(r, predictor, len(windows), scale)
    return residual


def robust_residuals(r: np.ndarray, predictor: Predictor, nwindows: int, scale: float) -> np.ndarray:
    """Residuals scaled per window by sqrt(s log(1 + c / s) / c), c the window's mean square:
    their sum of squares is the Cauchy loss sum_i n s log(1 + c_i / s) of the window costs."""
    c = predictor.window_mean_squares(r, nwindows)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(c > 0, np.sqrt(scale * np.log1p(c / scale) / c), 1.0)
    blocks = predictor.window_blocks(r, nwindows)
    return (blocks * (w[None, :, None] if r.ndim == 1 else w[None, :, None, :])).reshape(r.shape)


def cauchy_scale(costs: np.ndarray) -> float | None:
    """The loss scale: the median window cost (None where it is 0: least squares)."""
    s = float(np.median(costs))
    return s if s > 0 else None


def evaluate(predictor: Predictor, structure: Structure, train_pred: dict | None = None
             ) -> tuple[float, float, dict, dict]:
    """Train/test cost (mean squared normalised residual) and NRMSE per signal.

    ``train_pred``: the structure's predictions of the training windows, if already made.
    """
    tr, te = predictor.train, predictor.test
    if train_pred is None:
        (pred,) = predictor.predict([structure], np.concatenate([tr, te]))
        ptr = {k: v[: len(tr)] for k, v in pred.items()}
        pte = {k: v[len(tr):] for k, v in pred.items()}
    else:
        ptr, (pte,) = train_pred, predictor.predict([structure], te)
    c = lambda p, w: float(np.mean(np.nan_to_num(predictor.residuals(p, w), nan=_BAD) ** 2))  # noqa: E731
    return c(ptr, tr), c(pte, te), predictor.nrmse(ptr, tr), predictor.nrmse(pte, te)


def window_costs(predictor: Predictor, structure: Structure, windows: np.ndarray,
                 pred: dict | None = None) -> np.ndarray:
    """Mean squared normalised residual of each window (for paired comparisons); ``pred``: the
    structure's predictions of ``windows``, if already made."""
    if pred is None:
        (pred,) = predictor.predict([structure], windows)
    r = np.nan_to_num(predictor.residuals(pred, windows), nan=_BAD)
    return predictor.window_mean_squares(r, len(windows))


class Converged(Exception):
    """Raised from the Jacobian callback when the Gauss-Newton step is shorter than the tolerance."""


class Objective:
    """One window set's vectorised residual for mujoco.minimize, with the FD Jacobian and the
    step-length stopping rule. It remembers the last Jacobian (with its point and residual) and
    the predictions of the last single-point evaluation, so that neither is recomputed after
    the fit."""

    def __init__(self, predictor: Predictor, structure: Structure, names, windows, lo, hi, tol_se: float,
                 scale: float | None = None):
        self.seen: dict = {}
        self.accepted: dict = {}  # the last Jacobian point's predictions (``seen`` when it was taken)
        self._residual = residual_matrix(lambda structs, w: predictor.predictions(structs, w), structure, names,
                                         windows, predictor, self.seen, scale)
        # The Jacobian's columns, 1e-8 from a point whose model was found stable, are not checked
        # again (``Predictor.predict(assume_stable=True)``).
        self._fd_residual = residual_matrix(lambda structs, w: predictor.predictions(structs, w, assume_stable=True),
                                            structure, names, windows, predictor, None, scale)
        self._stable_at = (lambda x: False) if structure is None else (
            lambda x: predictor.stable(structure.from_vector(x, names)))
        self.bounds = [lo[:, None], hi[:, None]]
        self.lo, self.hi, self.tol_se = lo, hi, tol_se
        self.jac_at: tuple | None = None  # (x, r, jac) of the last Jacobian
        self.steps_se: list[float] = []
        self.costs: list[float] = []  # r'r at each Jacobian
        self.m = 1  # residual entries

    def residual(self, x: np.ndarray) -> np.ndarray:
        r = self._residual(x)
        if r.ndim == 2 and r.shape[1] == 1 and self.costs and self.steps_se[-1] < FAIL_SE \
                and float(r[:, 0] @ r[:, 0]) >= self.costs[-1]:
            raise Converged  # a failed trial step near the optimum (FAIL_SE)
        return r

    def jacobian(self, x: np.ndarray, r: np.ndarray) -> np.ndarray:
        self.accepted = dict(self.seen)
        jac, _ = minimize.jacobian_fd(self._fd_residual if self._stable_at(x[:, 0]) else self._residual, x, r, EPS, 0,
                                      self.bounds)
        self.jac_at = (x[:, 0].copy(), r[:, 0].copy(), jac)
        rr = float(r[:, 0] @ r[:, 0])
        self.m = r.shape[0]
        self.costs.append(rr)
        self.steps_se.append(gauss_newton_step_se(jac, r[:, 0], x[:, 0], self.lo, self.hi))
        s2 = residual_variance(r[:, 0], x.shape[0])
        gained = (self.costs[-1 - STALL_ITER] - rr) / max(s2, 1e-300) if len(self.costs) > STALL_ITER else np.inf
        if self.steps_se[-1] < self.tol_se or gained < self.tol_se ** 2:
            raise Converged
        return jac

    def final(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(r, J, the point both were taken at) for the fit's x: the last Jacobian's if it was
        taken there or one step below XTOL away (the LM's own stop), else a fresh one at x."""
        if self.jac_at is not None:
            xj, rj, jac = self.jac_at
            if np.linalg.norm(x - xj) <= XTOL * (XTOL + np.linalg.norm(x)):
                return rj, jac, xj
        r, jac = fd_jacobian(self._residual, x, self.bounds)
        return r, jac, x.copy()

    def prediction(self, x: np.ndarray) -> dict | None:
        """The predictions at x if the last single-point evaluation was there."""
        for seen in (self.seen, self.accepted):
            if "x" in seen and np.array_equal(seen["x"], x):
                return seen["pred"]
        return None


def fd_jacobian(residual, x: np.ndarray, bounds, r: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(r, J) of a ``residual_matrix`` function at the point x (1-d), J by mujoco.minimize's
    forward differences within ``bounds``; ``r``: the residual at x where the caller has it."""
    r = residual(x[:, None]) if r is None else r[:, None]
    jac, _ = minimize.jacobian_fd(residual, x[:, None], r, EPS, 0, bounds)
    return r[:, 0], jac


def gauss_newton_step_se(jac: np.ndarray, r: np.ndarray, x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """Length of the undamped Gauss-Newton step in standard errors of the fit: sqrt(g' H^+ g / s^2)
    with g = J'r, H = J'J over the parameters not held by a bound, s^2 = r'r / (m - n). The
    step d = H^+ g measured in the metric of the parameters' covariance s^2 H^-1: a value of 0.1
    means no combination of the parameters would move by more than 0.1 of its standard error."""
    g = jac.T @ r
    free = ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))
    if not free.any():
        return 0.0
    j = jac[:, free]
    lam, vec = np.linalg.eigh(j.T @ j)
    keep = lam > max(float(lam.max()), 1e-300) * EIG_FLOOR
    d2 = float(np.sum((vec[:, keep].T @ g[free]) ** 2 / lam[keep]))
    return float(np.sqrt(d2 / max(residual_variance(r, x.size), 1e-300)))


def _lm(obj: Objective, x0: np.ndarray, max_iter: int, on_iter) -> tuple[np.ndarray, int, bool, float]:
    """(x, iterations, capped, loss): mujoco.minimize's LM from x0 until the step rule, its xtol
    or max_iter; ``capped`` where max_iter stopped it, the cost still falling; ``loss`` its
    objective per residual at x."""
    iterations, rr = 0, np.nan

    def count(log):
        nonlocal iterations, rr
        iterations, rr = len(log), 2.0 * float(log[-1].objective)
        on_iter(iterations, rr, obj.m)
    try:
        x, _ = minimize.least_squares(x0, obj.residual, bounds=[obj.lo, obj.hi], jacobian=obj.jacobian,
                                      max_iter=max_iter, xtol=XTOL, mu_min=MU_MIN,
                                      mu_factor=MU_FACTOR, verbose=minimize.Verbosity.SILENT, iter_callback=count)
    except Converged:
        on_iter(iterations + 1, obj.costs[-1], obj.m)
        return obj.jac_at[0], iterations + 1, False, obj.costs[-1] / obj.m
    # The log holds the start too: max_iter + 1 entries where the cap stopped the LM; its last
    # entry is the loss at the returned point.
    return x.reshape(-1), iterations, iterations > max_iter, rr / obj.m


def fit(predictor: Predictor, structure: Structure, names=None, *, max_iter: int = 25,
        windows: np.ndarray | None = None, progress=None, robust: bool = False, restarts: int = 0,
        subset_only: bool = False) -> FitResult:
    """Least-squares fit of the parameters ``names`` (default: all) of ``structure``; with
    ``robust``, under the Cauchy loss over windows (module doc).

    With ``restarts`` > 0 the fit is also run staged, where the structure has effects that refine
    another (``refinements``): those held at their values while the rest are fitted, then all
    from there, the order a diagnosis adds them in (the memory of 2SEP fitted at once with the
    levels it shapes can settle with them in a wrong valley: concealed dynamic_friction seed 0,
    pre-sliding stiffness 306 for 785). The lower training cost is kept; where that still ends
    with a parameter on a bound or a training cost above FAR_ABOVE times the noise floor
    (``Predictor.noise_floor``), the fit is run again from ``restart_points`` (the recording's
    initial values, then seeded random starts), the lowest training cost kept.

    With ``subset_only``, the fit stops after its first LM phase (the seeded COARSE_SHARE of
    the windows) and returns that point scored on the held-out windows only (``partial`` set);
    ``finish`` takes it on to exactly the result the whole fit gives. Where the windows are too
    few for two phases, the whole fit is run.
    """
    if subset_only:
        if restarts:
            raise ValueError("fit: subset_only and restarts cannot be combined")
        key = _memo_key(structure, names, max_iter, windows, robust)
        memo = _MEMO.setdefault(predictor, {})
        if key is not None and key in memo and memo[key][0] is structure.start:
            return dataclasses.replace(memo[key][1])
        result = _fit_once(predictor, structure, names, max_iter, windows, progress, robust, subset_only=True)
        if key is not None:
            memo[key] = (structure.start, result)
        return dataclasses.replace(result)
    result = _fit_once(predictor, structure, names, max_iter, windows, progress, robust)
    if restarts <= 0:
        return result
    tried = [result]
    fitted = [p.name for p in structure.params if names is None or p.name in names]
    basics = [n for n in fitted if n not in refinements(structure)]
    if 0 < len(basics) < len(fitted):
        first = _fit_once(predictor, structure, basics, max_iter, windows, progress, robust)
        tried.append(_fit_once(predictor, first.structure, names, max_iter, windows, progress, robust))
        tried[-1].seconds += first.seconds
        tried[-1].rollouts += first.rollouts
    best = lowest(tried)
    if best.on_bound or best.cost_train > FAR_ABOVE * predictor.noise_floor:
        tried += fits_from(predictor, restart_points(structure, names, restarts, predictor.design.seed), names,
                           max_iter=max_iter, windows=windows, progress=progress, robust=robust)
        best = lowest(tried)
    return best


def fits_from(predictor: Predictor, starts: list[Structure], names=None, *, max_iter: int = 25,
              windows: np.ndarray | None = None, progress=None, robust: bool = False,
              subset_only: bool = False) -> list[FitResult]:
    """One fit of ``names`` from each of ``starts`` (``restart_points``), as ``fit`` without
    restarts fits."""
    return [fit(predictor, s, names, max_iter=max_iter, windows=windows, progress=progress, robust=robust,
                subset_only=subset_only) for s in starts]


def lowest(tried: list[FitResult]) -> FitResult:
    """The fit of ``tried`` (one structure's, from several starts) that ends at the lowest
    training cost: its subset phase's loss where they stopped after it (``subset_only``); its
    ``starts``, ``seconds`` and ``rollouts`` count all of them."""
    best = min(tried, key=lambda r: r.partial.loss if r.partial is not None else r.cost_train)
    return dataclasses.replace(best, starts=sum(r.starts for r in tried), seconds=sum(r.seconds for r in tried),
                               rollouts=sum(r.rollouts for r in tried))


def fitted_on_both(predictor: Predictor, a: FitResult, b: FitResult) -> np.ndarray:
    """Which training windows both fits were fitted on: one a fit left out (its start open to
    that model) holds no evidence between them."""
    return ~np.isin(predictor.train, a.left_out + b.left_out)


def training_ratio(predictor: Predictor, result: FitResult, reference: FitResult, from_start: bool = False) -> float:
    """``result``'s least-squares training cost over ``reference``'s on the windows both were
    fitted on: their subset phase's where both stopped after it (``subset_only``), else the
    training windows neither left out. A fit of a structure that contains the reference's, with
    at least its parameters free, cannot end above 1 where it converged. With ``from_start``, over
    the cost the reference started at (its subset phase's start, or a whole fit's
    ``start_cost``, over all training windows): the bound of a fit started there with fewer
    parameters free."""
    if result.partial is not None and reference.partial is not None:
        return float(result.partial.loss / (reference.partial.start_loss if from_start else reference.partial.loss))
    if result.partial is not None or reference.partial is not None:
        raise ValueError("training_ratio: a fit stopped after its subset phase compares only with another one")
    if from_start:
        if not np.isfinite(reference.start_cost):
            raise ValueError("training_ratio: the reference kept no least-squares start cost (a robust fit)")
        return float(np.mean(result.train_costs) / reference.start_cost)
    keep = fitted_on_both(predictor, result, reference)
    return float(np.mean(result.train_costs[keep]) / np.mean(reference.train_costs[keep]))


def refinements(structure: Structure) -> set[str]:
    """The parameters of the structure's effects that refine another (``Effect.requires``: a
    Stribeck dip or 2SEP's memory on a Coulomb level, a play or hysteresis on a gear stiffness)."""
    return {p.name for e in structure.effects if EFFECTS[e].requires for p in EFFECTS[e].params}


def restart_points(structure: Structure, names, count: int, seed: int) -> list[Structure]:
    """``count`` starting points: the parameters' initial values (the recording's estimates
    where the structure has them) unless the structure starts there already, then seeded draws
    around them, RESTART_DECADES (normal std) in log coordinates, uniform over the range for
    linear ones, clipped to the bounds."""
    params = [p for p in structure.params if names is None or p.name in names]
    initial = structure.with_values({p.name: p.initial for p in params})
    points = [] if np.array_equal(initial.vector(names), structure.vector(names)) else [initial]
    rng = np.random.default_rng([seed, count])
    while len(points) < count:
        values = {}
        for p in params:
            if p.log:
                values[p.name] = float(np.clip(p.initial * 10.0 ** rng.normal(0.0, RESTART_DECADES), p.lo, p.hi))
            else:
                values[p.name] = float(rng.uniform(p.lo, p.hi))
        points.append(structure.with_values(values))
    return points


@dataclass
class _Partial:
    """A fit between its two LM phases (``fit(subset_only=True)``): what ``finish`` needs."""

    structure: Structure
    names: list[str]
    windows: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    x: np.ndarray
    done: int
    max_iter: int
    robust: bool
    loss: float  # the subset phase's objective per residual at x
    start_loss: float  # the same at the start
    finished: "FitResult | None" = field(default=None, repr=False, compare=False)  # ``finish``'s result, once made


def _fit_once(predictor: Predictor, structure: Structure, names, max_iter: int, windows, progress,
              robust: bool, subset_only: bool = False) -> FitResult:
    """One fit from the structure's values (``fit``).

    Two LM phases: on a seeded quarter of the windows until the step is within COARSE_SE of
    that subset's standard errors, then on all windows until it is within STEP_SE of theirs
    (each LM run at most ``max_iter`` iterations; the second repeated while the loss scale
    falls, SCALE_ROUNDS). ``progress(iteration, cost)`` gets the mean loss per residual over
    the windows of the phase. ``subset_only``: stop between the phases (``fit``).
    """
    start = time.perf_counter()
    roll0 = predictor.rollouts
    windows = predictor.train if windows is None else np.asarray(windows)
    # The structure's own order: vector() and from_vector() use it, so the labels must too.
    wanted = None if names is None else set(names)
    names = [p.name for p in structure.params if wanted is None or p.name in wanted]
    lo, hi = structure.bounds(names)
    x = np.clip(structure.vector(names), lo, hi)
    done, capped, loss, start_loss = 0, False, np.nan, np.nan
    subset = coarse_windows(windows, predictor.design.seed)
    if subset is not None:
        scale = _scale_at(predictor, structure, names, robust, x, subset)
        coarse = Objective(predictor, structure, names, subset, lo, hi, COARSE_SE, scale)
        x, done, capped, loss = _lm(coarse, x, max_iter, _reporter(progress, 0))
        start_loss = coarse.costs[0] / coarse.m if coarse.costs else loss  # the first Jacobian's point is the start
    state = _Partial(structure, names, windows, lo, hi, x, done, max_iter, robust, loss, start_loss)
    if subset_only and subset is not None:
        best = structure.from_vector(x, names)
        (pred,) = predictor.predict([best], predictor.test)
        cost_test = float(np.mean(np.nan_to_num(predictor.residuals(pred, predictor.test), nan=_BAD) ** 2))
        return FitResult(best, float("nan"), cost_test, {}, predictor.nrmse(pred, predictor.test),
                         iterations=done, rollouts=predictor.rollouts - roll0,
                         seconds=time.perf_counter() - start, coarse_iterations=done, coarse_capped=capped,
                         partial=state)
    return _second_phase(predictor, state, progress, start, roll0)


def finish(predictor: Predictor, result: FitResult, progress=None) -> FitResult:
    """A fit stopped after its subset phase (``fit(subset_only=True)``) taken on over all its
    windows: the result the whole fit gives, its time and rollouts counting both parts."""
    if result.partial is None:
        return result
    if result.partial.finished is None:
        start, roll0 = time.perf_counter(), predictor.rollouts
        out = _second_phase(predictor, result.partial, progress, start, roll0)
        out.seconds += result.seconds
        out.rollouts += result.rollouts
        result.partial.finished = out
    return dataclasses.replace(result.partial.finished)


# A fit stopped after its subset phase, and its finishing, are functions of the predictor and
# their arguments alone; a diagnosis asks for the same ones again where a round leaves its model
# as it was (an effect refused as a stand-in, the model without it not kept: the next round
# screens the same candidates against the same fit). Each subset fit is made once per predictor
# (its finishing kept on its ``_Partial``), and a copy of the result returned (its ``rollouts``
# and ``seconds`` those the fit took when made).
_MEMO: "weakref.WeakKeyDictionary[Predictor, dict]" = weakref.WeakKeyDictionary()


def _memo_key(structure: Structure, names, max_iter: int, windows, robust: bool) -> tuple | None:
    """What a subset fit depends on besides its predictor, hashable (None where the plant is not)."""
    try:
        hash(structure.nominal)
    except TypeError:
        return None
    return (structure.effects, tuple(sorted(structure.values.items())), tuple(sorted(structure.settings.items())),
            structure.nominal, structure.gear_ratio, id(structure.start),
            None if names is None else tuple(names), max_iter,
            None if windows is None else tuple(np.asarray(windows).tolist()), robust)


def _scale_at(predictor: Predictor, structure: Structure, names, robust: bool, x, w, obj=None):
    """The loss scale at x: median window cost over ``w`` (None: least squares)."""
    if not robust:
        return None
    return cauchy_scale(window_costs(predictor, structure.from_vector(x, names), w,
                                     None if obj is None else obj.prediction(x)))


def _second_phase(predictor: Predictor, st: _Partial, progress, start: float, roll0: float) -> FitResult:
    """The LM on all of the fit's windows from the subset phase's end (``_fit_once``), then the
    intervals and the train/held-out scores."""
    structure, names, windows, lo, hi, x, done = st.structure, st.names, st.windows, st.lo, st.hi, st.x, st.done
    coarse_done = done
    start_cost = float("nan")
    # The windows the fitted model leaves undetermined (``Predictor.undetermined``) are left out
    # and the LM goes on without them, once. Not the start's: a start far off (the catalogue's
    # values) flags the very breakaways that show the effect, and a fit without them misses it.
    for redecided in (False, True):
        scale = _scale_at(predictor, structure, names, st.robust, x, windows)
        for _ in range(SCALE_ROUNDS):
            obj, obj_scale = Objective(predictor, structure, names, windows, lo, hi, STEP_SE, scale), scale
            x, k, _, _ = _lm(obj, x, st.max_iter, _reporter(progress, done))
            if done == 0 and scale is None and obj.costs:  # the fit's own start, on all its windows
                start_cost = obj.costs[0] / obj.m
            done += k
            new = None if scale is None else _scale_at(predictor, structure, names, st.robust, x, windows, obj)
            if new is None or new > scale / 2:
                break
            scale = new
        best = structure.from_vector(x, names)
        more = np.zeros(0, int) if redecided else predictor.undetermined(best, windows)
        if more.size == 0:
            break
        windows = np.setdiff1d(windows, more)
    r, jac, at = obj.final(x)
    spans, warnings, optimum = intervals(jac, r, x, lo, hi, names, best, predictor.window_blocks(jac, len(windows)),
                                         predictor.window_blocks(r, len(windows)))
    train = predictor.train
    ptr = obj.prediction(x) if np.array_equal(windows, train) else None
    if ptr is None:
        (ptr,) = predictor.predict([best], train)
    ctr, cte, ntr, nte = evaluate(predictor, best, ptr)
    return FitResult(best, ctr, cte, ntr, nte, spans, warnings, iterations=done,
                     train_costs=window_costs(predictor, best, train, ptr),
                     left_out=tuple(int(w) for w in np.setdiff1d(st.windows, windows)),
                     rollouts=predictor.rollouts - roll0, seconds=time.perf_counter() - start,
                     coarse_iterations=coarse_done, robust=st.robust, start_cost=start_cost,
                     on_bound=best.stand_in_bounds(names, x),
                     at_optimum=_AtOptimum(optimum, names, windows, obj_scale, at))


@dataclass(frozen=True)
class _AtOptimum:
    """A fit's optimum (``intervals.Optimum``) with what its cost needs: the parameters' names,
    the windows and the robust loss's scale (None: least squares), and the point the intervals'
    Jacobian was taken at (the optimum or one LM step below XTOL from it). The Jacobian itself
    is not kept: it is the size of the residual times the parameters (~75 MB a fit of a
    10-minute recording) and a diagnosis holds many fits; the one checked takes it anew there,
    the same numbers (``jacobian``)."""

    optimum: Optimum
    names: list[str]
    windows: np.ndarray
    scale: float | None
    point: np.ndarray


def check_intervals(predictor: Predictor, result: FitResult, names, biased=None, twin: Twin | None = None) -> FitResult:
    """The fit with the intervals of ``names`` checked against the model itself
    (``intervals.profile_intervals``): each end moved to where the windowed cost, the other
    parameters following their first-order re-fit, rises as much as the interval assumes, or
    the parameter flagged where the cost is not quadratic over it; then those of ``biased``
    (default ``names``) widened by the step's bias (``step_bias``) and by the fit's own
    (``twin_bias``). A few rollouts of the fit's windows per end (PROFILE_EVALS at most), three
    for the step's bias and a fit from the estimate for the twin's, counted in ``rollouts``;
    ``twin``: the result's ``Twin``, where the caller has made it already."""
    at = result.at_optimum
    biased = names if biased is None else biased
    if at is None or not (names or biased):
        return result
    roll0, start = predictor.rollouts, time.perf_counter()
    residual = _at_fit(predictor, result.structure, at)
    spans, warnings, _ = profile_intervals(lambda xs: np.sum(residual(xs) ** 2, axis=0), at.optimum, at.names,
                                           result.structure, names, result.intervals, result.warnings)
    twin_rollouts = 0.0
    if biased:
        shift = step_bias(predictor, result.structure, at, residual)
        if shift is not None:
            spans, warnings = widened(result.structure, at, biased, shift, spans, warnings, _step_biased)
        shift, twin_rollouts = twin_bias(predictor, result, at, twin)
        if shift is not None:
            spans, warnings = widened(result.structure, at, biased, shift, spans, warnings, _twin_biased)
    return dataclasses.replace(result, intervals=spans, warnings=warnings, at_optimum=None,  # checked once
                               rollouts=result.rollouts + predictor.rollouts - roll0 + twin_rollouts,
                               seconds=result.seconds + time.perf_counter() - start)


def _at_fit(predictor: Predictor, structure: Structure, at: "_AtOptimum"):
    """The residual function of ``structure`` over the fit's windows and under its loss (``at``)."""
    return residual_matrix(lambda structs, w: predictor.predictions(structs, w), structure, at.names, at.windows,
                           predictor, None, at.scale)


def jacobian(residual, at: "_AtOptimum", r_opt: np.ndarray) -> np.ndarray:
    """The Jacobian the fit's intervals were computed from, taken again at its point (``at``) of
    the fit's residual function (``_at_fit``): p rollouts of the fit's windows, one more where
    that point is not the optimum, whose residual ``r_opt`` is given."""
    r = r_opt if np.array_equal(at.point, at.optimum.x) else None
    return fd_jacobian(residual, at.point, [at.optimum.lo[:, None], at.optimum.hi[:, None]], r)[1]


def reported(predictor: Predictor, result: FitResult, twin: Twin | None = None) -> FitResult:
    """``result`` as ``mjjoint fit`` and ``mjjoint.fit`` report it: every interval widened by its
    estimate's step bias and the fit's own (``step_bias``, ``twin_bias``; the profile check is
    the diagnosis's, for the effects it names, a few rollouts an end)."""
    return check_intervals(predictor, result, [], biased=list(result.intervals), twin=twin)


# The fitted model's step error converges at first order (docs/design.md, "Integration"): the
# estimate's distance to physics without a step is about this multiple of its move from the
# model's step to half of it.
STEP_BIAS_FACTOR = 2.0
# Singular values of the Jacobian below this share of the largest span directions the fit does
# not determine (``intervals.EIG_FLOOR`` on J'J): the bias has no component along them.
STEP_RCOND = 1e-7
# What a widened interval's warning says: the interval is calibrated, the estimate biased.
STEP_BIASED = "the model's step biases it more than the noise scatters it"
WIDENED = "its 95 % interval is widened to hold that"


def step_bias(predictor: Predictor, structure: Structure, at: "_AtOptimum", residual) -> np.ndarray | None:
    """The estimate's discretisation bias in the optimiser's coordinates, or None where the
    model at half the step is not stable: the Gauss-Newton move of the optimum when the model's
    step is halved, the data kept (-(J'J)^+ J' (r_h/2 - r_h) at the fit's windows and loss),
    times STEP_BIAS_FACTOR. A recording of physics has no step; the model's own error at its
    step is sub-noise in every signal and still moves well-determined parameters by more than
    their noise intervals (a Bouc-Wen gear's elastic share recorded at half the step: 0.2-0.4 %
    off against intervals of 0.1-0.2 %)."""
    fine = structure.at_timestep(structure.nominal.timestep / 2.0)
    if not predictor.stable(fine):
        return None
    x = at.optimum.x
    coarse = residual(x)[:, 0]
    halved = _at_fit(predictor, fine, at)(x)[:, 0]
    move = np.linalg.lstsq(jacobian(residual, at, coarse), coarse - halved, rcond=STEP_RCOND)[0]
    return STEP_BIAS_FACTOR * move


def twin_bias(predictor: Predictor, result: FitResult, at: "_AtOptimum",
              twin: Twin | None = None) -> tuple[np.ndarray | None, float]:
    """(The fit's own bias in the optimiser's coordinates, or None where the model has no twin of
    the recording; the rollouts it took): minus the move of the same fit (its parameters,
    windows and loss) repeated on a noisy twin the fitted model makes of the recording
    (``identify.twin``), started at the estimate, the twin's truth. What the fit moves a right
    model by there is what reconstructing the windows' start states from the samples does to it
    (velocities differentiated over a stencil, hidden states led in): a systematic move, the same
    on a twin without noise, which the intervals' noise model (each window's start error its
    own) does not hold: a dead time estimated 3-5 us short against intervals of +-2-4 us
    (``tests/test_twin_bias.py``). One draw of the noise therefore measures it. ``twin``: the
    result's ``Twin``, made here where None."""
    twin = (twin or Twin(predictor, result.structure)).draw(np.random.default_rng(predictor.design.seed),
                                                            predictor.fit_signals)
    if twin is None:
        return None, 0.0
    refit = fit(twin, result.structure, at.names, max_iter=TWIN_ITER, windows=at.windows, robust=result.robust)
    if not np.isfinite(refit.cost_train):
        return None, refit.rollouts
    return at.optimum.x - refit.structure.vector(at.names), refit.rollouts


# The twin's fit starts at its truth and moves by the bias alone: a few iterations.
TWIN_ITER = 10


def _step_biased(name: str, value: str, without: str) -> str:
    return (f"{name} = {value}: {STEP_BIASED} (without a step about {without}: its move at half the step, "
            f"linearised, doubled); {WIDENED}")


def _twin_biased(name: str, value: str, without: str) -> str:
    return (f"{name} = {value}: the fit moves it on the model's own twin of the recording more than the noise "
            f"scatters it (its windows' start states, reconstructed from the samples; without that bias about "
            f"{without}); {WIDENED}")


def widened(structure: Structure, at: "_AtOptimum", names, shift: np.ndarray, spans: dict, warnings: list,
            why) -> tuple[dict, list]:
    """``spans`` of ``names`` widened by their estimates' bias ``shift`` (``step_bias``,
    ``twin_bias``): each interval joined with itself moved by the shift, so the end on the
    shift's side moves by it; a warning (``why(name, value, value without the bias)``) says so
    where the shift exceeds the interval's half-width on that side."""
    params = {p.name: p for p in structure.params}
    spans, warnings = dict(spans), list(warnings)
    for name in names:
        if name not in at.names or name not in spans:
            continue
        j, p = at.names.index(name), params[name]
        x, d = at.optimum.x[j], float(shift[j])
        low, high = spans[name]
        end = high if d > 0 else low
        if not (np.isfinite(d) and d != 0.0 and np.isfinite(end) and (end > 0 or not p.log)):
            continue
        moved = p.from_unit(p.to_unit(end) + d)
        spans[name] = (low, moved) if d > 0 else (moved, high)
        if abs(d) > abs(p.to_unit(end) - x):
            warnings.append(why(name, f"{p.from_unit(x):.4g}", f"{p.from_unit(x + d):.4g}"))
    return spans, warnings


def _reporter(progress, done: int):
    """The LM's iteration callback: ``progress(iteration, mean squared residual)``."""
    def on_iter(iteration: int, rr: float, m: int) -> None:
        if progress is not None:
            progress(done + iteration, rr / m)
    return on_iter


def coarse_windows(windows: np.ndarray, seed: int) -> np.ndarray | None:
    """The seeded share of the windows the first LM phase runs on (None: too few for two phases)."""
    n = max(COARSE_MIN, int(round(COARSE_SHARE * len(windows))))
    if COARSE_SHARE <= 0 or 2 * n > len(windows):
        return None
    return np.sort(np.random.default_rng(seed).choice(windows, n, replace=False))
