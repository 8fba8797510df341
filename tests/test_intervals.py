"""Parameter intervals with the windows as independent units, and their check against the cost
itself (mjjoint/identify/intervals.py).

Linear least squares, where every quantity is known exactly, stands in for the windowed fit:
a window's residuals share one error, as a window with an off start state shares its offset.
A parameter that enters the model through a cube stands in for one whose cost is far from
quadratic over its interval.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from mjjoint.assets.drive import DriveSpec
from mjjoint.identify.effect import Param
from mjjoint.identify.intervals import (UNCALIBRATED, independent_variances, intervals, profile_intervals,
                                        window_jackknife_variances)
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
    spans, warnings, _ = intervals(jac, r, x, lo, hi, names, structure, *blocks)
    first, second = (spans[n] for n in names)
    assert first[0] < structure.values[names[0]] < first[1] < 1.1 * structure.values[names[0]]
    assert second[0] <= 1e-300 and second[1] >= 1e300
    assert any(w.startswith(f"{names[1]} ") and "poorly identifiable" in w for w in warnings)
    assert not any(w.startswith(f"{names[0]} ") for w in warnings)


# Two linear parameters of a synthetic model (``intervals`` reads only names, bounds, from_unit).
LINEAR = SimpleNamespace(params=(Param("demo.a", 0.0, -100.0, 100.0, log=False),
                                 Param("demo.theta", 0.0, -100.0, 100.0, log=False)))
NAMES = [p.name for p in LINEAR.params]
LO, HI = np.full(2, -100.0), np.full(2, 100.0)


def _checked(jac, r, x, cost, blocks):
    """(linearised spans, checked spans, checked warnings, cost evaluations) of the demo model."""
    spans, warnings, optimum = intervals(jac, r, x, LO, HI, NAMES, LINEAR, *blocks)
    return (spans, *profile_intervals(cost, optimum, NAMES, LINEAR, NAMES, spans, warnings))


def test_a_quadratic_cost_keeps_the_linearised_interval_at_one_evaluation_per_end():
    """Linear least squares: the cost is exactly quadratic, each end stands at its first
    evaluation (with the one at the estimate, five for two parameters)."""
    a, y = _windowed_problem(np.random.default_rng(4))
    x, r = _fit(a, y)
    cost = lambda xs: np.sum((a.reshape(-1, 2) @ xs - y.reshape(-1, 1)) ** 2, axis=0)  # noqa: E731
    spans, checked, warnings, evaluations = _checked(a.reshape(-1, 2), r.ravel(), x, cost, (a[None], r[None]))
    assert evaluations == 5
    assert not warnings
    for name in NAMES:
        np.testing.assert_allclose(checked[name], spans[name], rtol=1e-9)


def test_a_parameter_whose_cost_is_far_from_quadratic_gets_an_interval_that_covers():
    """y = a + (theta - 5)^3 u + window error + noise with theta = 5: the cost is quadratic in
    (theta - 5)^3, not in theta, and the linearised interval theta_hat +- 1.96 se(theta), with
    se(theta) = se((theta - 5)^3) / 3 (theta_hat - 5)^2, holds 5 only when
    |theta_hat - 5|^3 < 0.65 se((theta - 5)^3): about half the time. The checked interval is
    the profile's, quadratic in (theta - 5)^3: it covers at the nominal rate. (The offset keeps
    the interval narrower than the value: a wider one is flagged poorly identifiable, unchecked.)"""
    rng = np.random.default_rng(5)
    trials, linearised, checked, flagged = 300, 0, 0, 0
    for _ in range(trials):
        u = rng.normal(0.1, 1.0, size=(WINDOWS, SAMPLES))
        y = 1.0 + 0.3 * rng.normal(size=(WINDOWS, 1)) + rng.normal(size=(WINDOWS, SAMPLES))
        design = np.stack([np.ones_like(u), u], axis=-1)
        lin, _ = _fit(design, y)  # (a, (theta - 5)^3)
        x = np.array([lin[0], 5.0 + np.cbrt(lin[1])])
        r = x[0] + (x[1] - 5.0) ** 3 * u - y
        jac = np.stack([np.ones_like(u), 3 * (x[1] - 5.0) ** 2 * u], axis=-1)
        cost = lambda xs: np.sum((xs[0] + (xs[1] - 5.0) ** 3 * u.reshape(-1, 1) - y.reshape(-1, 1)) ** 2,  # noqa: E731
                                 axis=0)
        spans, spans_checked, warnings, _ = _checked(jac.reshape(-1, 2), r.ravel(), x, cost, (jac[None], r[None]))
        linearised += spans["demo.theta"][0] <= 5.0 <= spans["demo.theta"][1]
        if any(w.startswith("demo.theta ") for w in warnings):
            flagged += 1
        else:
            checked += spans_checked["demo.theta"][0] <= 5.0 <= spans_checked["demo.theta"][1]
    assert linearised / trials < 0.7
    assert flagged / trials < 0.1
    assert checked / (trials - flagged) > 0.9


def test_an_estimate_that_is_not_the_minimum_over_its_interval_is_flagged():
    """A second, lower valley inside the interval: no end on the cost's own scale exists there,
    so the interval is not reported as calibrated."""
    a, y = _windowed_problem(np.random.default_rng(6))
    x, r = _fit(a, y)
    spans, warnings, optimum = intervals(a.reshape(-1, 2), r.ravel(), x, LO, HI, NAMES, LINEAR, a[None], r[None])
    valley = x[1] + 0.9 * optimum.half[1]

    def cost(xs):
        quadratic = np.sum((a.reshape(-1, 2) @ xs - y.reshape(-1, 1)) ** 2, axis=0)
        well = np.exp(-((xs[1] - valley) / (0.2 * optimum.half[1])) ** 2)
        return quadratic - 10 * float(r.ravel() @ r.ravel()) * well
    _, checked = profile_intervals(cost, optimum, NAMES, LINEAR, ["demo.theta"], spans, warnings)[:2]
    flags = [w for w in checked if w.startswith("demo.theta ")]
    assert len(flags) == 1 and UNCALIBRATED in flags[0]
    assert not any(w.startswith("demo.a ") for w in checked)
