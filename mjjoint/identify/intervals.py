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

Both are linearised: they assume the cost is quadratic over the interval, which a dead zone's
width (flat-ish below the play, a kink above it) is not. ``profile_intervals`` checks chosen
intervals against the cost itself: each end stands where the cost rises there as the quadratic
model says, moves to where it does (the profile likelihood's end, on the same scale) where not,
and the parameter is flagged where no such end is found (docs/diagnosis.md, "Intervals").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Eigenvalues of J^T J below this share of the largest are taken as unidentifiable directions,
# by the intervals and by the fit's step rule alike.
EIG_FLOOR = 1e-14
Z95 = 1.96  # a 95 % interval's half-width in standard errors
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


@dataclass(frozen=True)
class Optimum:
    """A fit's optimum as the check of its intervals (``profile_ends``) needs it, in the
    optimiser's coordinates: the point, its bounds, J'J there, the intervals' half-widths, and
    the parameters the intervals flagged (held on the check's path)."""

    x: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    jtj: np.ndarray
    half: np.ndarray
    held: np.ndarray


def intervals(jac, r, x, lo, hi, names, structure, jac_blocks, r_blocks):
    """95 % intervals in physical units from the Jacobian at the optimum, warnings, and the
    ``Optimum`` their check starts from (``profile_ends``).

    ``jac_blocks``, ``r_blocks``: the same Jacobian and residual grouped by window; each
    half-width is the wider of the independent-residual and the window-jackknife one (module doc).
    """
    jac = np.asarray(jac)
    var, lam = independent_variances(jac, r)
    var = np.maximum(var, window_jackknife_variances(jac_blocks, r_blocks))
    half = Z95 * np.sqrt(var)
    params = {p.name: p for p in structure.params}
    out, warnings, held = {}, [], np.zeros(len(names), dtype=bool)
    for j, name in enumerate(names):
        out[name], flag = _span(params[name], x[j], x[j] - half[j], x[j] + half[j], near_bound(x[j], lo[j], hi[j]))
        if flag:
            warnings.append(flag)
            held[j] = True
    with np.errstate(over="ignore"):  # a singular J^T J: cond = inf, reported below
        cond = float(lam.max() / max(lam.min(), 1e-300))
    if cond > 1e12:
        warnings.append(f"parameters are nearly collinear (cond(J^T J) = {cond:.1e})")
    optimum = Optimum(np.array(x, dtype=float), np.asarray(lo, dtype=float), np.asarray(hi, dtype=float),
                      jac.T @ jac, half, held)
    return out, warnings, optimum


def _span(p, x: float, low: float, high: float, at_bound: bool) -> tuple[tuple[float, float], str | None]:
    """((low, high) in physical units, the warning it calls for or None) of parameter ``p`` at
    ``x`` with an interval ``low`` .. ``high`` in the optimiser's coordinate."""
    a, b = p.from_unit(low), p.from_unit(high)
    span, value = (min(a, b), max(a, b)), p.from_unit(x)
    half = max(x - low, high - x)
    if at_bound:
        return span, f"{p.name} = {value:.4g} sits on its bound [{p.lo:g}, {p.hi:g}]"
    if (half > np.log(2.0)) if p.log else (half > max(abs(value), 1e-12)):
        return span, (f"{p.name} = {value:.4g} is poorly identifiable from this recording "
                      f"(95 % interval {span[0]:.3g} .. {span[1]:.3g})")
    return span, None


# The check of an interval against the model (``profile_ends``). The interval assumes the cost
# is quadratic over it; where the cost at an end rises within PROFILE_TOL (in sqrt(rise), which
# is linear in the distance for a quadratic cost) of the rise the quadratic model has there,
# the end is kept; otherwise it moves to where the cost does rise that much (the profile
# likelihood interval, on the jackknife's scale), found within PROFILE_EVALS evaluations.
PROFILE_TOL = 0.1
# A moved end may fall short of the rise by this share of PROFILE_TOL only, or lie this share of
# PROFILE_TOL of its distance past the last point short of it: a search stopped early must not
# narrow the interval it corrects.
PROFILE_SHORT = 0.2
PROFILE_EVALS = 8
PROFILE_GROWTH = 10.0  # a step short of the rise grows at most this much per evaluation
UNCALIBRATED = "interval not calibrated: the cost is not quadratic over it"


@dataclass
class _End:
    """One end's search (``profile_ends``) for the step d along ``direction`` (its own
    parameter's entry is +-1) at which R(d) = sqrt(rise) reaches T = sqrt(t) (R is linear in d
    for a quadratic cost): the closest points (d, R) tried below and above T, up to ``dmax``
    (the bound)."""

    j: int
    direction: np.ndarray
    t: float
    dmax: float
    d: float
    below: tuple = (0.0, 0.0)
    above: tuple | None = None
    before: tuple | None = None  # the point below tried before ``below`` (the outward step)
    moved: int = 0  # which side the last point replaced (-1 below, 1 above)
    found: float | None = None
    failed: str | None = None

    def advance(self, root: float) -> None:
        """Take R at the current d and choose the next d: outward until T is passed (at most
        PROFILE_GROWTH times the step), then inside the bracket; each step where a power law
        R ~ d^k through the two points reaches T (exact for a quadratic cost, and for one whose
        curvature grows or fades as a power of the distance), a bisection where the same side
        of the bracket moved twice running (a curved R cannot hold one end still)."""
        target = np.sqrt(self.t)
        side = -1 if root < target else 1
        if side < 0:
            self.before, self.below = self.below, (self.d, root)
        else:
            self.above = (self.d, root)
        if self.above is None:
            d1 = self.d
            step = _power_crossing(self.before, self.below, target) if root > self.before[1] else np.inf
            self.d = float(min(np.clip(step, 1.5 * d1, PROFILE_GROWTH * d1), self.dmax))
            return
        (a, _), (b, _) = self.below, self.above
        if side == self.moved:
            d = np.sqrt(a * b) if a > 0 else 0.5 * (a + b)
        else:
            d = _power_crossing(self.below, self.above, target)
        self.moved = side
        self.d = float(np.clip(d, a + 0.05 * (b - a), b - 0.05 * (b - a)))


def _power_crossing(p: tuple, q: tuple, target: float) -> float:
    """The d at which the power law R = c d^k through the points p, q ((d, R)) reaches
    ``target``; the straight line where p is the origin (or R is not positive at both)."""
    (d0, r0), (d1, r1) = p, q
    if d0 > 0 and r0 > 0 and r1 > 0 and r1 != r0 and d1 != d0:
        k = np.log(r1 / r0) / np.log(d1 / d0)
        if k > 0:
            return float(d0 * (target / r0) ** (1.0 / k))
    return float(d0 + (target - r0) * (d1 - d0) / (r1 - r0)) if r1 != r0 else np.inf


def profile_ends(cost, optimum: Optimum, checked) -> tuple[dict[int, tuple[float, float]], dict[int, str], int]:
    """The ends of the checked parameters' intervals where the cost itself rises as much as the
    quadratic model does at the intervals' ends (PROFILE_TOL): ({j: (low, high)}, optimiser's
    coordinate), {j: why an end was not found}, and the points evaluated.

    ``cost(X)``: r'r at each column of X (parameters x points), of the residual whose J'J the
    optimum holds; the rise is counted from its value at x (one evaluation more). The other
    parameters follow the path on which, to first order, they are re-fitted (the profile:
    x + d H^-1 e_j / (H^-1)_jj); parameters the intervals flagged are held. For a quadratic
    cost (linear least squares) the ends are the intervals' own. All ends are searched
    together, one ``cost`` call per round.
    """
    free = np.flatnonzero(~optimum.held)
    hinv = np.linalg.pinv(optimum.jtj[np.ix_(free, free)], rcond=EIG_FLOOR, hermitian=True)
    ends: list[_End] = []
    for j in checked:
        half = optimum.half[j]
        if optimum.held[j] or not np.isfinite(half):
            continue
        k = int(np.searchsorted(free, j))
        path = np.zeros(optimum.x.size)
        path[free] = hinv[:, k] / hinv[k, k]
        t = half ** 2 / hinv[k, k]
        for sign in (-1.0, 1.0):
            dmax = float(optimum.hi[j] - optimum.x[j] if sign > 0 else optimum.x[j] - optimum.lo[j])
            ends.append(_End(j, sign * path, t, dmax, min(half, dmax)))
    if not ends:
        return {}, {}, 0
    # The cost at x itself: the fit's residual may be that of its last Jacobian's point, a step
    # below the optimiser's tolerance away, which is more than a narrow interval's width.
    centre = float(np.asarray(cost(optimum.x[:, None]), dtype=float)[0])
    evaluations = 1
    for _ in range(PROFILE_EVALS):
        active = [e for e in ends if e.found is None and e.failed is None]
        if not active:
            break
        points = np.column_stack([np.clip(optimum.x + e.d * e.direction, optimum.lo, optimum.hi) for e in active])
        rises = np.asarray(cost(points), dtype=float) - centre
        evaluations += len(active)
        for e, rise in zip(active, rises):
            if not rise >= 0:  # lower than the estimate (or NaN): the interval's centre is not the minimum
                e.failed = f"the cost falls below the estimate's {e.d:.3g} from it"
                continue
            g = np.sqrt(rise) - np.sqrt(e.t)
            tol = PROFILE_TOL * np.sqrt(e.t)
            own = e.above is None and e.before is None
            if (abs(g) <= tol if own else -PROFILE_SHORT * tol <= g <= tol) or (g < 0 and e.d >= e.dmax):
                e.found = e.d  # the rise reached, or not reached up to the bound: the interval ends there
                continue
            e.advance(float(np.sqrt(rise)))
            if e.above is not None and e.above[0] - e.below[0] <= PROFILE_SHORT * PROFILE_TOL * e.above[0]:
                e.found = e.above[0]  # bracketed closely: its outer end
    for e in ends:
        if e.found is None and e.failed is None:
            e.failed = f"its rise not found within {PROFILE_EVALS} evaluations"
    out, why = {}, {}
    for j in dict.fromkeys(e.j for e in ends):
        low, high = (e for e in ends if e.j == j)
        if low.failed or high.failed:
            why[j] = low.failed or high.failed
        else:
            out[j] = (optimum.x[j] - low.found, optimum.x[j] + high.found)
    return out, why, evaluations


def profile_intervals(cost, optimum: Optimum, names, structure, checked, spans: dict, warnings: list
                      ) -> tuple[dict, list, int]:
    """(spans, warnings, points evaluated) with the ``checked`` parameters' intervals checked
    against the cost (``profile_ends``): an end moved to where the cost rises as the interval
    assumes, or the parameter flagged (UNCALIBRATED) where no such end was found."""
    names = list(names)
    ends, why, evaluations = profile_ends(cost, optimum, [names.index(n) for n in checked if n in names])
    params = {p.name: p for p in structure.params}
    spans, warnings = dict(spans), list(warnings)
    for j, (low, high) in ends.items():
        spans[names[j]], flag = _span(params[names[j]], optimum.x[j], low, high, False)
        if flag:
            warnings.append(flag)
    for j, reason in why.items():
        warnings.append(f"{names[j]} = {params[names[j]].from_unit(optimum.x[j]):.4g}: {UNCALIBRATED} ({reason})")
    return spans, warnings, evaluations
