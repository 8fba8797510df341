"""95 % intervals of fitted parameters, robust to errors shared within a window.

The textbook interval of nonlinear least squares, s^2 (J^T J)^-1, assumes independent residuals.
Windowed prediction errors are not: a window whose start state is off (an unmeasured friction
memory, a biased start velocity) stays off for its whole length, so its hundreds of residuals
carry one error, not hundreds. Fitting the true structure to closed-loop recordings of a known
truth, that interval left the truth outside it for most parameters, some by more than ten
standard errors (CHANGELOG.md, "Benchmark history", has the measurement).

So the windows are treated as the independent units: the covariance is the delete-one-window
jackknife, linearised at the optimum (for linear least squares it is exact),

    d_w = (J'J - J_w'J_w)^+ J_w' r_w,    V = (G - 1) / G  sum_w (d_w - mean d)(d_w - mean d)'

(d_w: how far the estimate moves when window w is left out; G windows). It is the cluster-robust
covariance with each window's leverage taken into account, which matters here: a parameter's
information often sits in a few windows (a breakaway, a step). It is reported only where it is
wider than the independent-residual one (Angrist and Pischke, *Mostly Harmless Econometrics*,
Sec. 8.2: the larger of the two, since a robust estimate from few clusters can come out too
small), which also keeps directions that J'J does not determine at an infinite width. On the
same fits it covered the truth for all but a few parameters, each of those just past its end.
"""
from __future__ import annotations

import numpy as np

# Eigenvalues of J^T J below this share of the largest are taken as unidentifiable directions,
# by the intervals and by the fit's step rule alike.
EIG_FLOOR = 1e-14
# A parameter within this share of its range (in the optimiser's coordinate) from a bound sits
# on it: what it stands for lies at or beyond the bound, its value is a stand-in.
BOUND_SHARE = 1e-3


def residual_variance(r: np.ndarray, nparams: int) -> float:
    """The residual variance s^2 = r'r / (m - n) the intervals and the step rule are scaled by."""
    return float(r @ r) / max(r.size - nparams, 1)


def independent_variances(jac: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(diagonal of s^2 (J'J)^-1, eigenvalues of J'J): inf along directions below EIG_FLOOR."""
    lam, vec = np.linalg.eigh(jac.T @ jac)
    lam_max = max(float(lam.max()), 1e-300)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # unidentifiable -> inf
        inv_diag = np.sum(vec ** 2 / np.maximum(lam, lam_max * EIG_FLOOR)[None, :], axis=1)
        var = np.nan_to_num(residual_variance(r, jac.shape[1]) * inv_diag, nan=np.inf)
    return var, lam


def window_jackknife_variances(jac_blocks: np.ndarray, r_blocks: np.ndarray) -> np.ndarray:
    """Diagonal of the delete-one-window jackknife covariance (module doc).

    ``jac_blocks`` (signals, windows, samples, params) and ``r_blocks`` (signals, windows,
    samples): the Jacobian and residual of a fit grouped by window (``Predictor.window_blocks``).
    """
    # Per window: its share of J'J and of the gradient J'r (no copy of the Jacobian: a long
    # recording's is hundreds of MB).
    hw = np.einsum("swkp,swkq->wpq", jac_blocks, jac_blocks)
    gw = np.einsum("swkp,swk->wp", jac_blocks, r_blocks)
    h = hw.sum(axis=0)
    d = np.array([np.linalg.pinv(h - hw[w], hermitian=True) @ gw[w] for w in range(len(gw))])
    d -= d.mean(axis=0)
    g = len(gw)
    return (g - 1) / g * np.sum(d ** 2, axis=0)


def near_bound(x, lo, hi):
    """Whether x (the optimiser's coordinate) is within BOUND_SHARE of its range from a bound."""
    margin = BOUND_SHARE * (np.asarray(hi) - np.asarray(lo))
    return (np.asarray(x) <= lo + margin) | (np.asarray(x) >= hi - margin)


def intervals(jac, r, x, lo, hi, names, structure, jac_blocks, r_blocks):
    """95 % intervals in physical units from the Jacobian at the optimum, and warnings.

    ``jac_blocks``, ``r_blocks``: the same Jacobian and residual grouped by window; each
    half-width is the wider of the independent-residual and the window-jackknife one (module doc).
    """
    jac = np.asarray(jac)
    var, lam = independent_variances(jac, r)
    var = np.maximum(var, window_jackknife_variances(jac_blocks, r_blocks))
    half = 1.96 * np.sqrt(var)
    params = {p.name: p for p in structure.params}
    out, warnings = {}, []
    for j, name in enumerate(names):
        p = params[name]
        a, b = p.from_unit(x[j] - half[j]), p.from_unit(x[j] + half[j])
        out[name] = (min(a, b), max(a, b))
        value = p.from_unit(x[j])
        at_bound = near_bound(x[j], lo[j], hi[j])
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
