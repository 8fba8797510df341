"""Locate where a simulation departs from a recording of the same experiment.

The residual is r = measured - simulated. `residual_windows` says when it is large,
`condition_scores` under which operating condition it concentrates, and `locate` does both for
every recorded signal. The output is evidence for the step that names the missing physics.

Every condition score is on one scale, the share of residual variance (energy of the mean-free
residual) the condition accounts for, in [0, 1]:
- concentration conditions (near velocity reversals, small |delta|): (E - T) / (1 - T), where
  E is the residual energy share inside the condition's samples and T their time share; 0 when
  the residual is spread evenly, 1 when all of it sits there;
- regressions (sin/cos theta, harmonics of q, friction shapes and a friction level periodic
  in q, acceleration, delta): the fraction of residual variance explained by a least-squares
  fit on the regressors;
- resonance: the residual power share in a +-10 % band around a spectral peak, minus the larger
  of what the measured signal's spectrum puts there (motion-shaped errors are no resonance) and
  twice the residual's own local background (coloured noise is no resonance either);
- lag: the fraction of residual variance removed by time-shifting the simulation;
- hysteresis: (integral r d(delta))^2 / (integral r^2 |d(delta)| * integral |d(delta)|), the
  squared loop area of r against delta relative to the largest one this residual energy allows.

Noise threshold: each score is also computed for `n_permutations` null residuals holding the
same values with any relation to the conditions removed: the residual cut into NULL_BLOCK_S
blocks put back in random order (so that noise correlated over less than a block is not taken
for structure), or, for resonance, whose statistic such blocks would keep, sample by sample.
A score counts as significant when it exceeds both NULL_SIGMAS standard deviations above the
mean of its null scores and `min_effect` (default 5 %). The first guards short records and
smooth residuals, where chance fits are large; the second guards long ones, where a slowly
wandering residual can beat the permutations without pointing at any physics. When nothing is
significant, the residual concentrates nowhere that was looked at.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Iterator, Mapping, Sequence

import numpy as np
from scipy.fft import irfft, next_fast_len, rfft
from scipy.ndimage import uniform_filter1d
from scipy.signal import welch

from .features import sample_period
from .harmonics import harmonic_scores
from .window_median import window_medians

REVERSAL_WINDOW_S = 0.030   # [s]: stick-slip and backlash transients last tens of ms
SMALL_DELTA_QUANTILE = 0.2  # "small |delta|" = the 20 % of samples closest to zero deflection
MAX_HARMONIC = 40           # cycles per motor revolution searched for position-periodic effects
MIN_CYCLES = 0.1            # the longest period searched: ten motor revolutions (a friction level's)
PERIODS_IN_SPAN = 2         # a period searched repeats at least this often over the angle's recorded span
PERIOD_STEPS = 101          # real periods tried within half a cycle of the best whole one
STRIBECK_SPEEDS = (0.02, 0.05, 0.1, 0.2, 0.35)  # bump widths v, as fractions of the 95th-pct |qd|
RESONANCE_BAND = 0.1        # relative half-width of the band a resonance's power is counted in
WELCH_SEGMENTS = 4          # a Welch segment is at most 1/4 of the record: >= 7 averaged at 50 % overlap
RESONANCE_PEAK_RATIO = 2.0  # Welch scatter of a few segments reaches ~2x the true level
MAX_LAG_S = 0.050           # [s]: larger shifts are timing faults, not missing physics
NULL_SIGMAS = 4.0
NULL_BLOCK_S = 0.2          # [s]: residual correlation shorter than this is treated as noise
# Columns (residual + nulls) scored at once: NULL_BATCH, or as many more as hold NULL_BATCH_SAMPLES
# samples in all. The lag and resonance statistics hold several times a column per column, so
# this bounds the transient memory at a 10-minute 1 kHz record's batch of NULL_BATCH; a shorter
# record is scored in fewer, wider batches (each condition's regressors are built once a batch).
NULL_BATCH = 5
NULL_BATCH_SAMPLES = NULL_BATCH * 600_000
WINDOW_LEVEL = 0.25         # a window spans the stretch where the envelope stays above this x peak


def nrmse(measured: np.ndarray, simulated: np.ndarray) -> float:
    """Normalized RMS error: rms(measured - simulated) / std(measured)."""
    m = np.asarray(measured, dtype=float)
    s = np.asarray(simulated, dtype=float)
    if m.shape != s.shape:
        raise ValueError(f"measured {m.shape} and simulated {s.shape} differ in shape")
    if m.size == 0 or not (np.all(np.isfinite(m)) and np.all(np.isfinite(s))):
        raise ValueError("measured and simulated must be non-empty and finite")
    sd = float(np.std(m))
    if sd == 0.0:
        raise ValueError("measured signal is constant (zero std): NRMSE is undefined for it")
    return float(np.sqrt(np.mean((m - s) ** 2)) / sd)


@dataclass(frozen=True)
class Window:
    """A time window [t0, t1] s holding `energy_share` of the residual energy sum(r^2)."""

    t0: float
    t1: float
    energy_share: float


def residual_windows(
    t: np.ndarray, r: np.ndarray, n_windows: int = 3, min_width: float = 0.1
) -> list[Window]:
    """Up to `n_windows` disjoint windows holding most of the residual energy, largest first.

    The envelope is r^2 averaged over `min_width` seconds. Windows are picked greedily around
    the highest free envelope peak, spanning the contiguous stretch where the envelope stays
    above WINDOW_LEVEL x that peak, and at least `min_width` wide where free samples allow.
    """
    dt = sample_period(t)
    t = np.asarray(t, dtype=float)
    energy = np.asarray(r, dtype=float) ** 2
    if energy.shape != t.shape:
        raise ValueError(f"r has shape {energy.shape}, expected {t.shape} like t")
    total = float(energy.sum())
    if total == 0.0:
        return []
    half = max(int(round(min_width / dt)), 1) // 2
    envelope = uniform_filter1d(energy, 2 * half + 1, mode="nearest")
    free = np.ones(t.size, dtype=bool)
    windows = []
    for _ in range(n_windows):
        if not free.any():
            break
        peak = int(np.argmax(np.where(free, envelope, -np.inf)))
        lo, hi = _run_around(peak, free)
        lo_hi = _run_around(peak, free & (envelope >= WINDOW_LEVEL * envelope[peak]))
        left = max(lo, min(lo_hi[0], peak - half))
        right = min(hi, max(lo_hi[1], peak + half))
        free[left:right + 1] = False
        windows.append(Window(float(t[left]), float(t[right]), float(energy[left:right + 1].sum() / total)))
    return sorted(windows, key=lambda w: -w.energy_share)


def _run_around(i: int, mask: np.ndarray) -> tuple[int, int]:
    """First and last index of the run of True in `mask` containing index i."""
    gaps = np.flatnonzero(~mask)
    before, after = gaps[gaps < i], gaps[gaps > i]
    return (int(before[-1]) + 1 if before.size else 0, int(after[0]) - 1 if after.size else mask.size - 1)


@dataclass(frozen=True)
class ConditionScore:
    """How much of the residual concentrates under one operating condition (see module doc)."""

    name: str
    score: float
    threshold: float  # noise threshold: score must exceed it to count
    description: str
    params: Mapping[str, float] = field(default_factory=dict)  # e.g. k, frequency_hz, lag_ms: plain numbers

    @property
    def significant(self) -> bool:
        return self.score > self.threshold

    def as_dict(self) -> dict:
        return {
            "name": self.name,
            "score": float(self.score),
            "threshold": float(self.threshold),
            "significant": self.significant,
            "description": self.description,
            "params": {k: v.item() if isinstance(v, np.generic) else v for k, v in self.params.items()},
        }


@dataclass(frozen=True)
class _Condition:
    name: str
    # Scores every column of R (column 0: the residual, others: its permutations), and the
    # parameters found for column 0.
    evaluate: Callable[[np.ndarray], tuple[np.ndarray, dict[str, float]]]
    describe: Callable[[float, dict[str, float]], str]
    null: str = "block"  # how the null residuals are permuted: in blocks or sample by sample
    # Parameters worth finding for the residual alone (not its permutations): (residual, the
    # parameters ``evaluate`` found) -> more parameters.
    refine: Callable[[np.ndarray, dict[str, float]], dict[str, float]] | None = None


def _centered_basis(columns: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the mean-free regressors; degenerate directions dropped."""
    b = columns - columns.mean(axis=0)
    u, s, _ = np.linalg.svd(b, full_matrices=False)
    if s.size == 0 or s[0] == 0.0:
        return u[:, :0]
    return u[:, s > 1e-9 * s[0]]


def _explained(basis: np.ndarray, R: np.ndarray) -> np.ndarray:
    return np.sum((basis.T @ R) ** 2, axis=0) / np.sum(R**2, axis=0)


def _explains(score: float) -> str:
    return f"explains {score:.0%} of residual variance"


def _regression(name: str, regressor: np.ndarray, text: str) -> _Condition:
    basis = _centered_basis(regressor[:, None])
    return _Condition(name, lambda R: (_explained(basis, R), {}), lambda s, p: f"{text} ({_explains(s)})")


def _concentration(name: str, mask: np.ndarray, text: str) -> _Condition:
    time_share = float(mask.mean())

    def evaluate(R: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
        energy = R**2
        share = energy[mask].sum(axis=0) / energy.sum(axis=0)
        if not 0.0 < time_share < 1.0:  # no contrast between inside and outside
            return np.zeros(R.shape[1]), {"energy_share": float(share[0]), "time_share": time_share}
        score = np.clip((share - time_share) / (1.0 - time_share), 0.0, 1.0)
        return score, {"energy_share": float(share[0]), "time_share": time_share}

    def describe(score: float, p: dict[str, float]) -> str:
        return f"{text} ({p['energy_share']:.0%} of residual energy in {p['time_share']:.0%} of the time)"

    return _Condition(name, evaluate, describe)


def _real_k(angle: np.ndarray, r: np.ndarray, lo: float, hi: float, sign: np.ndarray | None = None) -> float:
    """The k in [lo, hi] (PERIOD_STEPS of them) whose harmonic of ``angle`` explains the most of
    residual ``r`` (``harmonic_scores``, ``sign`` as there), to three decimals."""
    grid = np.linspace(lo, hi, PERIOD_STEPS)
    scores = harmonic_scores(angle, grid[0], (grid[-1] - grid[0]) / (PERIOD_STEPS - 1), PERIOD_STEPS, r[:, None], sign)
    return round(float(grid[np.argmax(scores[:, 0])]), 3)


def _periodic(name: str, coordinate: str, angle: np.ndarray, first: int = 1) -> _Condition:
    """Periodic in an angle at k = ``first`` .. MAX_HARMONIC cycles per revolution (the score),
    the best whole k reported, and the best real k within half a cycle of it (``k_real``: a
    period need not divide the revolution)."""
    def evaluate(R: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
        per_k = harmonic_scores(angle, first, 1.0, MAX_HARMONIC + 1 - first, R)
        return per_k.max(axis=0), {"k": int(np.argmax(per_k[:, 0])) + first}

    def refine(r: np.ndarray, params: dict[str, float]) -> dict[str, float]:
        return {"k_real": _real_k(angle, r, max(params["k"] - 0.5, 0.5), params["k"] + 0.5)}

    return _Condition(
        name, evaluate,
        lambda s, p: f"periodic in {coordinate} at {p['k']} cycles per revolution ({_explains(s)})",
        refine=refine,
    )


def _longest(q: np.ndarray, periods: float) -> tuple[float, float]:
    """(the fewest cycles per revolution that repeat ``periods`` times over q's recorded span, at
    least MIN_CYCLES; a quarter cycle over that span, the step a scan of real periods takes)."""
    span = float(np.ptp(q)) if q.size else 0.0
    if not span > 0:
        return 1.0, 1.0
    return max(MIN_CYCLES, periods * 2.0 * math.pi / span), math.pi / (2.0 * span)


def real_periodic(name: str, coordinate: str, angle: np.ndarray, periods: float, max_steps: int) -> _Condition:
    """Periodic in an angle at a real k, scanned from the longest period that repeats ``periods``
    times over its span to MAX_HARMONIC cycles per revolution in steps of a quarter cycle over the
    span (coarser where that would take more than ``max_steps``), the best refined about the best
    scanned: a torque of the rotor's own angle need not repeat a whole number of times a
    revolution, and scored at the nearest whole k it would explain little over a long travel."""
    first, fine = _longest(angle, periods)
    step = max(fine, (MAX_HARMONIC - first) / max_steps)
    count = max(1, int((MAX_HARMONIC - first) / step) + 1)

    def evaluate(R: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
        scores = harmonic_scores(angle, first, step, count, R)
        return scores.max(axis=0), {"k": round(first + step * int(np.argmax(scores[:, 0])), 3)}

    def refine(r: np.ndarray, params: dict[str, float]) -> dict[str, float]:
        return {"k_real": _real_k(angle, r, max(params["k"] - step, first), params["k"] + step)}

    return _Condition(
        name, evaluate,
        lambda s, p: f"periodic in {coordinate} at {p['k_real']:g} cycles per revolution ({_explains(s)})",
        refine=refine,
    )


def friction_periodic(q: np.ndarray, qd: np.ndarray, periods: float = PERIODS_IN_SPAN) -> _Condition:
    """A friction level periodic in the motor angle, sign(qd) [sin(k q), cos(k q)]: seen in a
    residual of the torque or the deflection, which such a level moves with the sign of the
    motion, and not by ``_periodic`` (its sign flips with every reversal). k is scanned from the
    longest period that repeats ``periods`` times over q's recorded span (at least MIN_CYCLES)
    in steps of a quarter cycle over that span up to one cycle per revolution, then at whole
    cycles to MAX_HARMONIC; the best real k is refined about the best scanned one."""
    sign = np.sign(qd)
    first, fine = _longest(q, periods)
    below = max(0, int(math.ceil((1.0 - first) / fine)))
    ks = np.concatenate([first + fine * np.arange(below), np.arange(1.0, MAX_HARMONIC + 1)])

    def evaluate(R: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
        scores = np.concatenate([harmonic_scores(q, first, fine, below, R, sign),
                                 harmonic_scores(q, 1.0, 1.0, MAX_HARMONIC, R, sign)])
        return scores.max(axis=0), {"k": round(float(ks[np.argmax(scores[:, 0])]), 3)}

    def refine(r: np.ndarray, params: dict[str, float]) -> dict[str, float]:
        k = params["k"]
        half = 0.5 if k >= 1.0 else fine
        return {"k_real": _real_k(q, r, max(k - half, first), k + half, sign)}

    return _Condition(
        "friction_periodic_q", evaluate,
        lambda s, p: f"a friction level periodic in q at {p['k']:g} cycles per revolution ({_explains(s)})",
        refine=refine,
    )


def _stribeck(qd: np.ndarray) -> _Condition:
    scale = float(np.percentile(np.abs(qd), 95))
    speeds = [f * scale for f in STRIBECK_SPEEDS]

    def evaluate(R: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
        per_v = np.stack([
            _explained(_centered_basis((np.sign(qd) * np.exp(-((qd / v) ** 2)))[:, None]), R) for v in speeds
        ])
        return per_v.max(axis=0), {"v": speeds[int(np.argmax(per_v[:, 0]))]}

    return _Condition(
        "stribeck", evaluate,
        lambda s, p: f"Stribeck-like bump sign(qd)*exp(-(qd/v)^2), v = {p['v']:.3g} rad/s ({_explains(s)})",
    )


def _hysteresis(delta_d: np.ndarray) -> _Condition:
    weight = np.abs(delta_d)

    def evaluate(R: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
        # d(delta) = delta_d dt on a uniform grid; dt cancels in the ratio.
        area = delta_d @ R
        bound = (weight @ R**2) * weight.sum()
        score = np.divide(area**2, bound, out=np.zeros_like(area), where=bound > 0)
        return score, {"direction": float(np.sign(area[0]))}

    def describe(score: float, p: dict[str, float]) -> str:
        turn = "clockwise" if p["direction"] > 0 else "counter-clockwise"
        return (f"hysteresis loop of r against delta, {turn} "
                f"(area {score:.0%} of the largest for this residual)")

    return _Condition("hysteresis", evaluate, describe)


def _resonance(dt: float, measured: np.ndarray) -> _Condition | None:
    """Resonance condition, or None when the record is too short to resolve one.

    Searched from about 9 frequency bins (9 / (record length / WELCH_SEGMENTS)) up to Nyquist / 1.4,
    where a band and its flanks fit: for 6 s at 1 kHz, about 9-357 Hz.
    """
    fs = 1.0 / dt
    if measured.size < WELCH_SEGMENTS:
        return None
    nperseg = 2 ** int(math.log2(measured.size / WELCH_SEGMENTS))
    f = np.fft.rfftfreq(nperseg, dt)
    idx = np.arange(f.size)
    # Band +-RESONANCE_BAND around each bin, at least +-2 bins so one bin's scatter is averaged;
    # flanks of three band half-widths beyond it on either side hold the background.
    lo = np.minimum(np.searchsorted(f, f * (1 - RESONANCE_BAND)), idx - 2)
    hi = np.maximum(np.searchsorted(f, f * (1 + RESONANCE_BAND), side="right") - 1, idx + 2)
    flank_lo, flank_hi = idx - 4 * (idx - lo), idx + 4 * (hi - idx)
    # Only bins whose flanks fit between DC (drift) and Nyquist (halved by Welch): a one-sided
    # background would make any spectrum's edge look like a peak.
    ok = (flank_lo >= 1) & (flank_hi <= f.size - 2)
    if not ok.any():
        return None
    centers, lo, hi, flank_lo, flank_hi = idx[ok], lo[ok], hi[ok], flank_lo[ok], flank_hi[ok]

    def band_share(p: np.ndarray) -> np.ndarray:
        c = np.concatenate([np.zeros((1,) + p.shape[1:]), np.cumsum(p, axis=0)])
        return np.divide(c[hi + 1] - c[lo], c[-1], out=np.zeros_like(c[lo]), where=c[-1] > 0)

    share_m = band_share(welch(measured, fs=fs, nperseg=nperseg)[1])

    def evaluate(R: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
        power = welch(R, fs=fs, nperseg=nperseg, axis=0)[1]
        # A resonance is a peak above the residual's own smooth spectrum: the background level is
        # the geometric mean of the flanks' median levels (a straight line in log-log, so the
        # slope of coloured noise is no peak), and power up to RESONANCE_PEAK_RATIO times it is
        # Welch scatter.
        level = np.sqrt(window_medians(power, flank_lo, lo) * window_medians(power, hi + 1, flank_hi + 1))
        background = RESONANCE_PEAK_RATIO * level * (hi - lo + 1)[:, None] / power.sum(axis=0)
        excess = band_share(power) - np.maximum(share_m[:, None], background)
        best = np.argmax(excess, axis=0)
        b = int(best[0])
        # Centroid of the power above background, re-centred until it settles: a damped peak
        # spans many bins, and in a few-segment Welch spectrum its highest bin wanders more.
        freq = float(f[centers[b]])
        for _ in range(3):
            k = int(np.clip(round(freq / f[1]), centers[0], centers[-1])) - centers[0]
            band = slice(lo[k], hi[k] + 1)
            above = np.clip(power[band, 0] - level[k, 0], 0.0, None)
            if not above.any():
                break
            freq = float(np.clip(f[band] @ above / above.sum(), f[lo[b]], f[hi[b]]))
        params = {"frequency_hz": freq, "band_lo_hz": float(f[lo[b]]), "band_hi_hz": float(f[hi[b]])}
        return np.clip(excess[best, np.arange(R.shape[1])], 0.0, 1.0), params

    def describe(score: float, p: dict[str, float]) -> str:
        return (f"resonance at {p['frequency_hz']:.1f} Hz ({score:.0%} of residual power in "
                f"{p['band_lo_hz']:.1f}-{p['band_hi_hz']:.1f} Hz beyond its background "
                "and the measured spectrum)")

    # Block permutation keeps a residual's spectrum above 1/block; only sample-wise
    # permutation gives the flat spectrum a resonance is tested against.
    return _Condition("resonance", evaluate, describe, null="sample")


def _best_lag(measured: np.ndarray, simulated: np.ndarray, max_lag: int) -> np.ndarray:
    """Shift d [samples] maximizing the correlation of measured(i) with simulated(i - d).

    `simulated` may hold several columns (one shift each). The correlation coefficient is taken
    over one fixed stretch of `measured`, max_lag from either end: a raw cross-correlation sums
    over a stretch that moves with the shift, which biases the broad peak of slow motions by
    milliseconds. The peak is refined to a fraction of a sample by a parabola through it and its
    neighbours. d > 0: measured lags simulated.
    """
    n, L = measured.shape[0], max_lag
    w = n - 2 * L
    m = np.zeros(n)
    m[L:n - L] = measured[L:n - L] - measured[L:n - L].mean()
    nfft = next_fast_len(2 * n)
    xc = irfft(rfft(m, nfft)[:, None] * np.conj(rfft(simulated, nfft, axis=0)), nfft, axis=0)
    xc = np.concatenate([xc[nfft - L:], xc[:L + 1]])  # rows: shifts -L..L
    # Variance of the simulated stretch paired with the fixed measured one, for every shift.
    start = L - np.arange(-L, L + 1)
    c1 = np.concatenate([np.zeros((1, simulated.shape[1])), np.cumsum(simulated, axis=0)])
    c2 = np.concatenate([np.zeros((1, simulated.shape[1])), np.cumsum(simulated**2, axis=0)])
    var = (c2[start + w] - c2[start]) - (c1[start + w] - c1[start]) ** 2 / w
    corr = xc / np.sqrt(np.maximum(var, 1e-300))
    cols = np.arange(corr.shape[1])
    k = np.argmax(corr, axis=0)
    y0, y1, y2 = (corr[np.clip(k + o, 0, 2 * L), cols] for o in (-1, 0, 1))
    curv = y0 - 2 * y1 + y2
    ok = (k > 0) & (k < 2 * L) & (curv < 0)
    frac = np.divide(0.5 * (y0 - y2), curv, out=np.zeros_like(curv), where=ok)
    return k - L + frac


def _lag(dt: float, measured: np.ndarray) -> _Condition:
    max_lag = min(int(round(MAX_LAG_S / dt)), measured.size // 4)

    def evaluate(R: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
        sims = measured[:, None] - R  # column 0 is the simulation (up to an offset), others surrogates
        lags = _best_lag(measured, sims, max_lag)
        inner = np.arange(max_lag, measured.size - max_lag)
        # The variance removed is measured at the nearest whole-sample shift: interpolating a
        # fractional one would average residual noise away and look like a lag explaining it.
        rows = inner[:, None] - np.round(lags).astype(int)
        shifted = measured[inner, None] - sims[rows, np.arange(R.shape[1])]
        scores = 1.0 - np.var(shifted, axis=0) / np.var(R[inner], axis=0)
        # A best shift on the search's bound is no located lag: a residual that drifts slowly
        # correlates best at the largest shift allowed, whatever its cause.
        scores[np.abs(lags) >= max_lag] = 0.0
        return np.clip(scores, 0.0, 1.0), {"lag_ms": float(lags[0] * dt * 1e3)}

    def describe(score: float, p: dict[str, float]) -> str:
        order = "measured behind simulated" if p["lag_ms"] >= 0 else "measured ahead of simulated"
        return (f"lag of {abs(p['lag_ms']):.1f} ms, {order} "
                f"(shifting removes {score:.0%} of residual variance)")

    return _Condition("lag", evaluate, describe)


def _conditions(
    conditions: Mapping[str, np.ndarray], dt: float | None, measured: np.ndarray | None
) -> list[_Condition]:
    """The candidate conditions the available arrays allow."""
    c = {k: np.asarray(v, dtype=float) for k, v in conditions.items()}
    out = []
    if "reversal_proximity" in c:
        near = c["reversal_proximity"] <= REVERSAL_WINDOW_S
        out.append(_concentration("reversal", near, "near motor velocity reversals"))
    if "abs_delta" in c:
        small = c["abs_delta"] <= np.quantile(c["abs_delta"], SMALL_DELTA_QUANTILE)
        out.append(_concentration("small_delta", small, "at small |delta|"))
    for key, text in (
        ("sin_theta", "correlated with sin(theta), gravity-like"),
        ("cos_theta", "correlated with cos(theta)"),
        ("accel", "proportional to link acceleration, inertia-like"),
        ("delta", "proportional to delta, stiffness-like"),
        ("theta", "proportional to theta, like a spring to the ground"),
    ):
        if key in c:
            out.append(_regression(key, c[key], text))
    if "q_mod" in c:
        # the unwrapped angle where given: a real number of cycles is periodic in it, not in q mod 2 pi
        out.append(_periodic("periodic_q", "q", c.get("q", c["q_mod"])))
    if "theta" in c:
        # one cycle of theta is sin_theta and cos_theta's
        out.append(_periodic("periodic_theta", "theta", c["theta"], first=2))
    if "qd" in c:
        qd = c["qd"]
        out.append(_regression("coulomb", np.sign(qd), "follows sign(qd), Coulomb-like"))
        out.append(_regression("viscous", qd, "proportional to qd, viscous-like"))
        out.append(_stribeck(qd))
        if "q" in c:
            out.append(friction_periodic(c["q"], qd))
    if "delta_d" in c:
        out.append(_hysteresis(c["delta_d"]))
    if dt is not None and measured is not None:
        resonance = _resonance(dt, measured)
        out += [_lag(dt, measured)] + ([] if resonance is None else [resonance])
    return out


def _block_permutation(x: np.ndarray, block: int, rng: np.random.Generator) -> np.ndarray:
    """x cut into blocks of `block` samples (at a random phase), put back in random order."""
    pieces = np.split(x, np.arange(int(rng.integers(block)), x.size, block))
    return np.concatenate([pieces[i] for i in rng.permutation(len(pieces))])


def condition_scores(
    r: np.ndarray,
    conditions: Mapping[str, np.ndarray],
    *,
    t: np.ndarray | None = None,
    measured: np.ndarray | None = None,
    n_permutations: int = 19,
    min_effect: float = 0.05,
    seed: int = 0,
    built: Sequence[_Condition] | None = None,
) -> list[ConditionScore]:
    """Scores of how much residual r = measured - simulated concentrates under each condition,
    highest first (scale and noise threshold: see the module docstring).

    `conditions` holds per-sample arrays as from `features.operating_conditions`; conditions
    whose arrays are missing are skipped. `built`: a caller's own conditions, scored instead.
    Resonance and lag need the time base `t` and the `measured` signal; without `t` the null
    also permutes sample by sample, as block length is a time. A residual without variance
    concentrates nowhere: the list is empty.
    """
    r = np.asarray(r, dtype=float)
    for key, v in conditions.items():
        if np.shape(v) != r.shape:
            raise ValueError(f"condition {key!r} has shape {np.shape(v)}, expected {r.shape} like r")
    if (t is None) != (measured is None):
        raise ValueError("resonance and lag need both t and measured")
    dt = None if t is None else sample_period(t)
    if measured is not None:
        measured = np.asarray(measured, dtype=float)
        if measured.shape != r.shape or np.shape(t) != r.shape:
            raise ValueError("t and measured must have the same shape as r")
    r0 = r - r.mean()
    if not np.any(r0):
        return []
    rng = np.random.default_rng(seed)
    block = 1 if dt is None else max(1, round(NULL_BLOCK_S / dt))
    permute = {"block": lambda: _block_permutation(r0, block, rng), "sample": lambda: rng.permutation(r0)}
    conds = _conditions(conditions, dt, measured) if built is None else list(built)
    per_batch = max(NULL_BATCH, NULL_BATCH_SAMPLES // r.size)
    values: dict[str, list[np.ndarray]] = {c.name: [] for c in conds}
    found: dict[str, dict[str, float]] = {}
    # All conditions of one null kind see the same null residuals, made ``per_batch`` columns at a
    # time (block ones first, as one stream of the seeded generator): the lag and resonance
    # statistics hold several times a column's size per column, which for all columns at once
    # grew with the record by ~1 kB per sample.
    for kind in ("block", "sample"):
        todo = n_permutations
        first = True
        while first or todo > 0:
            batch = [permute[kind]() for _ in range(min(todo, per_batch - first))]
            todo -= len(batch)
            R = np.column_stack(([r0] if first else []) + batch)
            for cond in (c for c in conds if c.null == kind):
                v, params = cond.evaluate(R)
                values[cond.name].append(v)
                if first:
                    found[cond.name] = params if cond.refine is None else {**params, **cond.refine(r0, params)}
            first = False
    scores = []
    for cond in conds:
        v = np.concatenate(values[cond.name])
        null = v[1:]
        threshold = min_effect
        if null.size > 1:
            threshold = max(threshold, float(null.mean() + NULL_SIGMAS * null.std(ddof=1)))
        score = float(v[0])
        scores.append(ConditionScore(cond.name, score, threshold, cond.describe(score, found[cond.name]),
                                     found[cond.name]))
    return sorted(scores, key=lambda s: -s.score)


@dataclass(frozen=True)
class SignalLocation:
    """Residual windows and condition scores of one signal."""

    signal: str
    nrmse: float
    windows: tuple[Window, ...]
    scores: tuple[ConditionScore, ...]

    def as_dict(self) -> dict:
        return {
            "signal": self.signal,
            "nrmse": self.nrmse,
            "windows": [[w.t0, w.t1, w.energy_share] for w in self.windows],
            "conditions": [s.as_dict() for s in self.scores],
        }


@dataclass(frozen=True)
class Location:
    """Where simulation and recording differ: `signal` is the one with the largest NRMSE."""

    signal: str
    signals: Mapping[str, SignalLocation]

    @property
    def worst(self) -> SignalLocation:
        return self.signals[self.signal]

    def as_dict(self) -> dict:
        """JSON-serializable: the worst signal's windows and conditions at top level, every
        signal's under "signals", and "nrmse" per signal."""
        worst = self.worst.as_dict()
        return {
            "signal": self.signal,
            "nrmse": {name: s.nrmse for name, s in self.signals.items()},
            "windows": worst["windows"],
            "conditions": worst["conditions"],
            "signals": {name: s.as_dict() for name, s in self.signals.items()},
        }


def located_conditions(where: dict) -> Iterator[tuple[str, dict]]:
    """(signal, condition) pairs of a location as ``locate(...).as_dict()`` gives it, signal by signal."""
    for signal, loc in where.get("signals", {}).items():
        for condition in loc.get("conditions", []):
            yield signal, condition


def locate(
    t: np.ndarray,
    measured: Mapping[str, np.ndarray],
    simulated: Mapping[str, np.ndarray],
    conditions: Mapping[str, np.ndarray],
    *,
    n_windows: int = 3,
    min_width: float = 0.1,
    n_permutations: int = 19,
    min_effect: float = 0.05,
    seed: int = 0,
) -> Location:
    """Windows and condition scores for every signal present in both `measured` and
    `simulated`; the signal with the largest NRMSE is the one reported first."""
    names = [k for k in measured if k in simulated]
    if not names:
        raise ValueError("no signal is present in both measured and simulated")
    per_signal = {}
    for name in names:
        m = np.asarray(measured[name], dtype=float)
        s = np.asarray(simulated[name], dtype=float)
        r = m - s
        per_signal[name] = SignalLocation(
            signal=name,
            nrmse=nrmse(m, s),
            windows=tuple(residual_windows(t, r, n_windows, min_width)),
            scores=tuple(condition_scores(
                r, conditions, t=t, measured=m,
                n_permutations=n_permutations, min_effect=min_effect, seed=seed,
            )),
        )
    worst = max(per_signal, key=lambda k: per_signal[k].nrmse)
    return Location(worst, per_signal)
