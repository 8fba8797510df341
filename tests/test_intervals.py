"""Parameter intervals with the windows as independent units (mjjoint/identify/intervals.py).

Linear least squares, where every quantity is known exactly, stands in for the windowed fit:
a window's residuals share one error, as a window with an off start state shares its offset.
"""
from __future__ import annotations

import numpy as np

from mjjoint.assets.drive import DriveSpec
from mjjoint.identify.intervals import independent_variances, intervals, window_jackknife_variances
from mjjoint.identify.structure import Structure

WINDOWS, SAMPLES = 30, 40


def _windowed_problem(rng, shared=1.0, own=0.3):
    """Design (windows, samples, 2) and data of y = A x + window error + sample noise, x = (1, -2)."""
    t = np.linspace(0.0, 1.0, SAMPLES)
    a = np.stack([np.ones((WINDOWS, SAMPLES)), rng.normal(size=(WINDOWS, 1)) + 0.3 * np.sin(6 * t)], axis=-1)
    y = a @ np.array([1.0, -2.0]) + shared * rng.normal(size=(WINDOWS, 1)) + own * rng.normal(size=(WINDOWS, SAMPLES))
    return a, y


def _fit(a, y):
    """(x, residual A x - y) of least squares over the windows given."""
    x = np.linalg.lstsq(a.reshape(-1, 2), y.ravel(), rcond=None)[0]
    return x, a @ x - y


def test_the_linearised_jackknife_is_the_exact_leave_one_window_out_for_linear_least_squares():
    a, y = _windowed_problem(np.random.default_rng(0))
    x, r = _fit(a, y)
    left_out = np.array([_fit(np.delete(a, w, 0), np.delete(y, w, 0))[0] for w in range(WINDOWS)])
    exact = (WINDOWS - 1) / WINDOWS * np.sum((left_out - left_out.mean(0)) ** 2, axis=0)
    np.testing.assert_allclose(window_jackknife_variances(a[None], r[None]), exact, rtol=1e-9)


def test_intervals_cover_the_truth_when_windows_share_errors_and_independent_ones_do_not():
    """95 % intervals over 400 recordings: the independent-residual one (s^2 (J'J)^-1) treats
    1200 residuals as 1200 errors where there are 30; the window jackknife does not."""
    rng = np.random.default_rng(1)
    truth = np.array([1.0, -2.0])
    hits_independent = hits_windows = 0
    trials = 400
    for _ in range(trials):
        a, y = _windowed_problem(rng)
        x, r = _fit(a, y)
        jac = a.reshape(-1, 2)
        indep = independent_variances(jac, r.ravel())[0]
        both = np.maximum(indep, window_jackknife_variances(a[None], r[None]))
        hits_independent += np.all(np.abs(x - truth) <= 1.96 * np.sqrt(indep))
        hits_windows += np.all(np.abs(x - truth) <= 1.96 * np.sqrt(both))
    # Two parameters each at 95 %: about 90 % jointly if the intervals are right.
    assert hits_independent / trials < 0.5
    assert hits_windows / trials > 0.85


def test_independent_errors_keep_the_independent_interval():
    """No shared error: the jackknife agrees with s^2 (J'J)^-1 (within its own scatter), so the
    intervals are not widened for nothing."""
    a, y = _windowed_problem(np.random.default_rng(2), shared=0.0)
    x, r = _fit(a, y)
    ratio = window_jackknife_variances(a[None], r[None]) / independent_variances(a.reshape(-1, 2), r.ravel())[0]
    assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio


def test_a_direction_the_data_do_not_determine_stays_unbounded_and_is_flagged():
    structure = Structure.create(("coulomb_friction",), DriveSpec(), 1.0)
    names = [p.name for p in structure.params]
    assert len(names) == 2
    rng = np.random.default_rng(3)
    jac = np.column_stack([rng.normal(size=(WINDOWS * SAMPLES)), np.zeros(WINDOWS * SAMPLES)])
    r = 0.01 * rng.normal(size=WINDOWS * SAMPLES)
    x = structure.vector(names)
    lo, hi = structure.bounds(names)
    blocks = jac.reshape(1, WINDOWS, SAMPLES, 2), r.reshape(1, WINDOWS, SAMPLES)
    spans, warnings = intervals(jac, r, x, lo, hi, names, structure, *blocks)
    first, second = (spans[n] for n in names)
    assert first[0] < structure.values[names[0]] < first[1] < 1.1 * structure.values[names[0]]
    assert second[0] <= 1e-300 and second[1] >= 1e300
    assert any(w.startswith(f"{names[1]} ") and "poorly identifiable" in w for w in warnings)
    assert not any(w.startswith(f"{names[0]} ") for w in warnings)
