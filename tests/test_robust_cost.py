"""The fit's robust cost over windows (identify/fit.py): a Cauchy loss on per-window costs.

Per-window prediction costs are heavy tailed (a window whose open-loop prediction is sensitive
to its own start state is missed even by the true model); least squares spends the parameters
on those few windows, the Cauchy loss counts them logarithmically.
"""
from __future__ import annotations

import numpy as np
import pytest

from mjjoint.assets.drive import DriveSpec
from mjjoint.identify.fit import cauchy_scale, fit, robust_residuals, window_costs
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign

from test_drive import FRICTION, TRUTH, closed_loop_recording

BASE = ("coulomb_friction", "viscous_friction", "input_offset")


@pytest.fixture(scope="module")
def predictor() -> Predictor:
    return Predictor(Measured.from_recording(closed_loop_recording(), 1.0, output=False), WindowDesign(length=0.5))


def test_the_weighted_residuals_sum_to_the_cauchy_cost_of_the_window_costs(predictor):
    nw = 6
    rng = np.random.default_rng(0)
    per_window = len(predictor.signals) * len(predictor.cols)
    r = rng.normal(size=(nw * per_window, 3)) * np.repeat(10.0 ** rng.uniform(-3, 1, size=(nw, 3)), per_window, 0)
    c = predictor.window_mean_squares(r, nw)
    assert c.shape == (nw, 3)
    assert c[2, 1] == pytest.approx(np.mean(r[2 * per_window:3 * per_window, 1] ** 2))
    s = 0.01
    rw = robust_residuals(r, predictor, nw, s)
    assert np.sum(rw ** 2, axis=0) == pytest.approx(per_window * np.sum(s * np.log1p(c / s), axis=0), rel=1e-12)
    # Least squares is the limit of a large scale; a window at zero cost stays at zero.
    assert robust_residuals(r, predictor, nw, 1e12) == pytest.approx(r, rel=1e-9)
    r[:per_window] = 0.0
    assert np.all(robust_residuals(r, predictor, nw, s)[:per_window] == 0.0)
    assert cauchy_scale(np.array([0.0, 0.0, 1.0])) is None and cauchy_scale(np.array([1.0, 2.0, 9.0])) == 2.0


def test_window_costs_are_each_windows_own_mean_square(predictor):
    start = Structure.create(BASE, DriveSpec(), 1.0)
    w = predictor.train[:5]
    together = window_costs(predictor, start, w)
    alone = [window_costs(predictor, start, w[i:i + 1])[0] for i in range(len(w))]
    assert together == pytest.approx(alone, rel=1e-12)


def test_a_few_unpredictable_windows_do_not_pull_the_robust_fit(predictor):
    """Three training windows whose measured angle runs off (no model can predict them) pull the
    least-squares fit away from the truth; the robust fit stays where the other windows put it."""
    meas = predictor.meas["q"]
    clean = meas.copy()
    bad = predictor.train[[1, 5, 9]]
    ramp = np.linspace(0.0, 1.0, predictor.nwin_samples) ** 2
    meas[bad] += 0.02 * ramp  # 20 mm drift over a window: far beyond what the drive's windows miss
    try:
        start = Structure.create(BASE, DriveSpec(), 1.0)
        error = {}
        for robust in (False, True):
            res = fit(predictor, start, max_iter=30, robust=robust)
            assert res.robust is robust  # the diagnosis refits no robust estimate a second time
            v = res.structure.values
            error[robust] = max(abs(v["inertia.motor"] / TRUTH.mass - 1),
                                abs(v["coulomb_friction.fc"] / FRICTION.fc - 1),
                                abs(v["viscous_friction.sigma"] / FRICTION.sigma - 1))
    finally:
        meas[:] = clean
    assert error[True] < 0.05 < error[False]
