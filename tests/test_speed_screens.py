"""Two-stage screening (diagnosis.loop._screen): a fit stopped after its subset phase and finished
later is the whole fit, and the screens left on the subset do not change which candidate wins."""
from __future__ import annotations

import numpy as np
import pytest

from mjjoint.assets.drive import DriveSpec
from mjjoint.diagnosis import loop
from mjjoint.diagnosis.clock import ScreenClock
from mjjoint.diagnosis.loop import DiagnoseOptions, _choose, _screen, continued
from mjjoint.identify.fit import evaluate, finish, fit
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign

from test_drive import closed_loop_recording

# The drive recording's truth has an input offset and a Coulomb level the start lacks or misses.
BASE = ("coulomb_friction", "viscous_friction")


@pytest.fixture(scope="module")
def predictor() -> Predictor:
    # 12 s in 0.5 s windows: 18 training windows, enough for the subset phase (8 of them).
    return Predictor(Measured.from_recording(closed_loop_recording(), 1.0, output=False), WindowDesign(length=0.5))


@pytest.mark.parametrize("robust", [False, True])
def test_a_fit_stopped_after_its_subset_phase_and_finished_is_the_whole_fit(predictor, robust):
    start = Structure.create((*BASE, "input_offset"), DriveSpec(), 1.0)
    whole = fit(predictor, start, max_iter=30, robust=robust)
    part = fit(predictor, start, max_iter=30, robust=robust, subset_only=True)
    assert part.partial is not None and part.coarse_iterations == whole.coarse_iterations > 0
    # The partial result is scored on the held-out windows at the point the subset phase reached.
    assert part.cost_test == evaluate(predictor, part.structure)[1]
    assert np.isnan(part.cost_train) and part.nrmse_train == {}
    done = finish(predictor, part)
    assert done.partial is None
    assert done.structure.values == whole.structure.values  # bit for bit
    assert (done.cost_train, done.cost_test, done.iterations) == (whole.cost_train, whole.cost_test, whole.iterations)
    assert done.intervals == whole.intervals
    # Only the partial's held-out scoring is extra.
    assert done.rollouts == pytest.approx(whole.rollouts + len(predictor.test) / len(predictor.starts))


def test_too_few_windows_for_a_subset_phase_give_the_whole_fit():
    pred = Predictor(Measured.from_recording(closed_loop_recording(6.0), 1.0, output=False), WindowDesign(length=0.5))
    start = Structure.create(BASE, DriveSpec(), 1.0)
    part = fit(pred, start, max_iter=5, subset_only=True)
    assert part.partial is None and part.coarse_iterations == 0 and np.isfinite(part.cost_train)
    assert finish(pred, part) is part
    with pytest.raises(ValueError, match="subset_only and restarts"):
        fit(pred, start, subset_only=True, restarts=1)


def test_which_subset_screens_go_on():
    names = ["a", "b", "c", "d", "e"]
    # The best always; others that gain at least half of what the best gains over the null.
    assert continued([0.5, 0.9, 0.7, 2.0, 0.95], 1.0, names) == [0, 2]
    # At most CONTINUE_MAX, by cost.
    assert continued([0.5, 0.52, 0.51, 0.53, 0.54], 1.0, names) == [0, 1, 2]
    # Nothing gains on the null: the best alone, so the acceptance tests still judge one.
    assert continued([1.2, 1.1, np.inf, 1.3, 1.05], 1.0, names) == [4]
    # A bundle takes its prerequisite screened alone along (``_decide`` prefers it if it passes).
    assert continued([0.9, 0.3, 1.5], 1.0, ["x", "linear_stiffness+backlash", "linear_stiffness"]) == [1, 2]
    # A screen still descending at its cap after a finer step goes on whatever its subset cost.
    assert continued([1.2, 1.1, np.inf, 1.3, 1.05], 1.0, names, descending=[3]) == [3, 4]
    assert continued([0.5, 0.9, 0.7, 2.0, 0.95], 1.0, names, descending=[0]) == [0, 2]


def test_a_subset_phase_stopped_by_its_cap_says_so(predictor):
    start = Structure.create((*BASE, "input_offset"), DriveSpec(), 1.0)
    capped = fit(predictor, start, max_iter=1, subset_only=True)
    done = fit(predictor, start, max_iter=30, subset_only=True)
    assert capped.coarse_capped
    assert not done.coarse_capped and done.coarse_iterations <= 30


def test_the_two_stage_screen_finds_the_candidate_finishing_every_screen_finds(predictor, monkeypatch):
    """The drive's missing offset (or its rival, a friction asymmetry) wins the screen either way,
    with the same finished fit, and the candidates left on the subset gain less."""
    base = fit(predictor, Structure.create(BASE, DriveSpec(), 1.0), max_iter=20)
    options = DiagnoseOptions(screen_iter=6)

    def screen():
        return _screen(predictor, base, {}, options, lambda m: None, ScreenClock(1), {}, set())
    _, two, rest = screen()
    assert rest and len(two) <= loop.CONTINUE_MAX
    monkeypatch.setattr(loop, "CONTINUE_MAX", 99)
    monkeypatch.setattr(loop, "CONTINUE_SHARE", -np.inf)
    monkeypatch.setattr(loop, "continued", lambda costs, *_: list(range(len(costs))))
    _, every, none_left = screen()
    assert none_left == {}
    best, _ = _choose(every, base.cost_test)
    assert best in {"input_offset", "friction_asymmetry"}
    assert _choose(two, base.cost_test)[0] == best
    assert two[best][0] == every[best][0] and two[best][1].structure.values == every[best][1].structure.values
    gain = base.cost_test - every[best][0]
    assert all(base.cost_test - every[k][0] < loop.TIE_SHARE * gain for k in rest)


def test_a_jacobian_at_a_stable_point_skips_the_columns_checks_and_equals_the_checked_one(predictor, monkeypatch):
    """The finite-difference columns around a point whose model is stable are not checked
    (``Predictor.predict(assume_stable=True)``); the Jacobian is the checked one bit for bit."""
    from mjjoint.identify import fit as fitmod
    from mjjoint.identify import windows as winmod

    start = Structure.create((*BASE, "input_offset"), DriveSpec(), 1.0)
    names = [p.name for p in start.params]
    lo, hi = start.bounds(names)
    x = start.vector(names)[:, None]
    checked = []
    real = winmod._stable
    monkeypatch.setattr(winmod, "_stable", lambda model: checked.append(model) or real(model))

    def jacobian(trust: bool) -> np.ndarray:
        obj = fitmod.Objective(predictor, start, names, predictor.train, lo, hi, fitmod.STEP_SE)
        if not trust:
            obj._stable_at = lambda x: False
        r = obj.residual(x)
        checked.clear()
        obj.jacobian(x, r)
        return obj.jac_at[2], len(checked)
    trusted, n_trusted = jacobian(True)
    full, n_full = jacobian(False)
    assert np.array_equal(trusted, full)
    assert n_full == len(names) and n_trusted == 1  # the point itself, from the memo
