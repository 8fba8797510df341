"""Fit a structure's parameters to a recording by windowed prediction error.

The optimiser is MuJoCo's own bounded Levenberg-Marquardt (``mujoco.minimize``), whose
residual is vectorised over parameter vectors: every finite-difference Jacobian is ONE batched
``mujoco.rollout`` of all windows for all perturbed models, spread over the cores. Parameters
are optimised in log coordinates where they span decades. Confidence intervals come from the
Jacobian at the optimum (s^2 (J^T J)^-1, s^2 from the residual); a parameter whose 95 %
interval is wider than its value, or that sits on a bound, is flagged.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from mujoco import minimize

from .structure import Structure
from .windows import Predictor

_BAD = 1e3  # residual given to an unstable (NaN) prediction: far worse than any real fit
# Stopping rule: the default xtol (1e-8) never fires on these residuals (~1e4 entries of
# O(0.01-1)), so LM ran to max_iter; a relative step of 1e-4 in the (log-)unit coordinates is
# ~1e-4 of a parameter, far inside any 95 % interval. (Raising mu tenfold per failed step,
# which also saved rollouts in scripts/bench_fit.py (c), stalled a drive fit in a narrow
# valley at 30 % Coulomb error: kept at MuJoCo's 10^0.1.)
XTOL = 1e-4


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

    def as_dict(self) -> dict:
        return {"structure": self.structure.describe(), "cost_train": self.cost_train,
                "cost_test": self.cost_test, "nrmse_train": self.nrmse_train, "nrmse_test": self.nrmse_test,
                "intervals_95": {k: list(v) for k, v in self.intervals.items()}, "warnings": self.warnings,
                "iterations": self.iterations, "rollouts": self.rollouts, "seconds": self.seconds}


def residual_matrix(pred_fn, structure: Structure, names, windows, predictor: Predictor):
    def residual(x: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(x.T).T if x.ndim == 1 else x
        structs = [structure.from_vector(x[:, i], names) for i in range(x.shape[1])]
        preds = pred_fn(structs, windows)
        cols = []
        for p in preds:
            r = predictor.residuals(p, windows)
            cols.append(np.where(np.isfinite(r), r, _BAD))
        return np.stack(cols, axis=1)
    return residual


def evaluate(predictor: Predictor, structure: Structure) -> tuple[float, float, dict, dict]:
    """Train/test cost (mean squared normalised residual) and NRMSE per signal."""
    tr, te = predictor.train, predictor.test
    both = np.concatenate([tr, te])
    (pred,) = predictor.predict([structure], both)
    ptr = {k: v[: len(tr)] for k, v in pred.items()}
    pte = {k: v[len(tr):] for k, v in pred.items()}
    c = lambda p, w: float(np.mean(np.nan_to_num(predictor.residuals(p, w), nan=_BAD) ** 2))  # noqa: E731
    return c(ptr, tr), c(pte, te), predictor.nrmse(ptr, tr), predictor.nrmse(pte, te)


def window_costs(predictor: Predictor, structure: Structure, windows: np.ndarray) -> np.ndarray:
    """Mean squared normalised residual of each window (for paired comparisons)."""
    (pred,) = predictor.predict([structure], windows)
    per = [np.mean(np.nan_to_num(predictor.residuals({k: v[i:i + 1] for k, v in pred.items()}, windows[i:i + 1]),
                                 nan=_BAD) ** 2) for i in range(len(windows))]
    return np.asarray(per)


def fit(predictor: Predictor, structure: Structure, names=None, *, max_iter: int = 25,
        windows: np.ndarray | None = None, progress=None) -> FitResult:
    """Least-squares fit of the parameters ``names`` (default: all) of ``structure``."""
    start = time.perf_counter()
    roll0 = predictor.rollouts
    windows = predictor.train if windows is None else windows
    # The structure's own order: vector() and from_vector() use it, so the labels must too.
    wanted = None if names is None else set(names)
    names = [p.name for p in structure.params if wanted is None or p.name in wanted]
    x0 = structure.vector(names)
    lo, hi = structure.bounds(names)
    x0 = np.clip(x0, lo, hi)
    residual = residual_matrix(predictor.predict, structure, names, windows, predictor)

    def on_iter(log):
        if progress is not None:
            progress(len(log), float(log[-1].objective))

    x, log = minimize.least_squares(x0, residual, bounds=[lo, hi], max_iter=max_iter,
                                    xtol=XTOL, verbose=minimize.Verbosity.SILENT, iter_callback=on_iter)
    best = structure.from_vector(x, names)
    intervals, warnings = _intervals(residual, x, lo, hi, names, best)
    ctr, cte, ntr, nte = evaluate(predictor, best)
    return FitResult(best, ctr, cte, ntr, nte, intervals, warnings, iterations=len(log),
                     rollouts=predictor.rollouts - roll0, seconds=time.perf_counter() - start)


def _intervals(residual, x, lo, hi, names, structure: Structure):
    """95 % intervals in physical units from the Jacobian at the optimum."""
    r0 = residual(x[:, None])
    jac, _ = minimize.jacobian_fd(residual=residual, x=x[:, None], r=r0, eps=1e-4, n_res=0,
                                  bounds=[lo[:, None], hi[:, None]])
    jac = np.asarray(jac)
    r = r0[:, 0]
    dof = max(r.size - x.size, 1)
    s2 = float(r @ r) / dof
    h = jac.T @ jac
    lam, vec = np.linalg.eigh(h)
    lam_max = max(float(lam.max()), 1e-300)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # unidentifiable -> inf
        inv_diag = np.array([np.sum(vec[j, :] ** 2 / np.maximum(lam, lam_max * 1e-14)) for j in range(len(x))])
        half = np.nan_to_num(1.96 * np.sqrt(s2 * inv_diag), nan=np.inf)
    params = {p.name: p for p in structure.params}
    out, warnings = {}, []
    for j, name in enumerate(names):
        p = params[name]
        a, b = p.from_unit(x[j] - half[j]), p.from_unit(x[j] + half[j])
        out[name] = (min(a, b), max(a, b))
        value = p.from_unit(x[j])
        at_bound = x[j] <= lo[j] + 1e-9 or x[j] >= hi[j] - 1e-9
        wide = (half[j] > np.log(2.0)) if p.log else (half[j] > max(abs(value), 1e-12))
        if at_bound:
            warnings.append(f"{name} = {value:.4g} sits on its bound [{p.lo:g}, {p.hi:g}]")
        elif wide:
            warnings.append(f"{name} = {value:.4g} is poorly identifiable from this recording "
                            f"(95 % interval {out[name][0]:.3g} .. {out[name][1]:.3g})")
    with np.errstate(over="ignore"):  # a singular J^T J: cond = inf, reported below
        cond = float(lam.max() / max(lam.min(), 1e-300))
    if cond > 1e12:
        warnings.append(f"parameters are nearly collinear (cond(J^T J) = {cond:.1e})")
    return out, warnings
