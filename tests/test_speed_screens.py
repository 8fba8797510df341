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


def test_a_whole_fit_keeps_the_cost_it_started_at_which_bounds_a_screen_started_there():
    """Where the windows are too few for a subset phase, a screen is a whole fit; the model it
    extends, fitted the same way, keeps the least-squares cost it started at on all training
    windows. A screen started there with fewer of the model's parameters free can end above that
    model's optimum without failing to converge, but not above its start: ``training_ratio``
    compares with the start where asked."""
    from mjjoint.identify.fit import training_ratio, window_costs

    pred = Predictor(Measured.from_recording(closed_loop_recording(6.0), 1.0, output=False), WindowDesign(length=0.5))
    base = Structure.create(BASE, DriveSpec(), 1.0)
    null = fit(pred, base, max_iter=5, subset_only=True)
    assert null.partial is None
    assert null.start_cost == pytest.approx(np.mean(window_costs(pred, base, pred.train)), rel=1e-12)
    assert null.cost_train < null.start_cost
    # a screen freeing only the candidate's own parameter, the base held at its start
    held = fit(pred, loop.with_candidate(base, "input_offset"), ["input_offset.offset"], max_iter=5)
    assert training_ratio(pred, held, null, from_start=True) == pytest.approx(held.cost_train / null.start_cost)
    assert training_ratio(pred, held, null, from_start=True) < 1.0
    assert training_ratio(pred, held, null) >= loop.UNRESOLVED_RATIO  # against the optimum: a false alarm
    assert np.isnan(fit(pred, base, max_iter=2, robust=True).start_cost)
    with pytest.raises(ValueError, match="start cost"):
        training_ratio(pred, held, fit(pred, base, max_iter=2, robust=True), from_start=True)


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
    _, two, rest, _ = screen()
    assert rest and len(two) <= loop.CONTINUE_MAX
    monkeypatch.setattr(loop, "CONTINUE_MAX", 99)
    monkeypatch.setattr(loop, "CONTINUE_SHARE", -np.inf)
    monkeypatch.setattr(loop, "continued", lambda costs, *_: list(range(len(costs))))
    _, every, none_left, _ = screen()
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


def test_the_subset_phases_loss_is_its_training_cost_and_compares_only_like_with_like(predictor):
    """A fit stopped after its subset phase keeps that phase's loss: the mean squared normalised
    residual of the subset's windows at the point reached, what ``training_ratio`` compares
    two such fits by; a finished fit is compared on the training windows instead, never a mix."""
    from mjjoint.identify.fit import coarse_windows, training_ratio, window_costs

    start = Structure.create((*BASE, "input_offset"), DriveSpec(), 1.0)
    part = fit(predictor, start, max_iter=30, subset_only=True)
    subset = coarse_windows(predictor.train, predictor.design.seed)
    assert part.partial.loss == pytest.approx(np.mean(window_costs(predictor, part.structure, subset)), rel=1e-12)
    null = fit(predictor, Structure.create(BASE, DriveSpec(), 1.0), max_iter=30, subset_only=True)
    assert training_ratio(predictor, part, null) == part.partial.loss / null.partial.loss < 1.0
    # against where the reference started: the bound of a screen started there with fewer parameters free
    assert null.partial.start_loss == pytest.approx(np.mean(window_costs(predictor, Structure.create(
        BASE, DriveSpec(), 1.0), subset)), rel=1e-12)
    assert training_ratio(predictor, part, null, from_start=True) == part.partial.loss / null.partial.start_loss
    whole = finish(predictor, part)
    assert training_ratio(predictor, whole, whole) == 1.0
    with pytest.raises(ValueError, match="subset phase"):
        training_ratio(predictor, whole, null)


def test_a_screen_ending_above_the_model_it_extends_in_training_is_fitted_again_from_other_starts(predictor):
    """A screen contains the model it extends (the offset at zero is that model), so a training
    cost above that model's is a fit that did not converge, not evidence: the drive's missing
    offset started at half its range and stopped after one iteration ends above the fitted
    base; from other starts of the offset (the catalogue's, then seeded draws; the rest where
    the first start had them) it explains the drive, the lowest training cost kept."""
    from mjjoint.identify.fit import restart_points, training_ratio

    base = fit(predictor, Structure.create(BASE, DriveSpec(), 1.0), max_iter=30)
    null = fit(predictor, base.structure, max_iter=30, subset_only=True)  # as ``_screen`` fits it
    trial = loop.with_candidate(base.structure, "input_offset", {"input_offset.offset": 50.0})
    options = DiagnoseOptions(screen_iter=8)
    stalled = fit(predictor, trial, max_iter=1, subset_only=True)
    assert training_ratio(predictor, stalled, null, from_start=True) >= loop.UNRESOLVED_RATIO
    lines = []
    res, start = loop._restarted_screen(predictor, "input_offset", stalled, trial, None, options, null, lines.append)
    starts = restart_points(trial, ["input_offset.offset"], loop.SCREEN_RESTARTS, predictor.design.seed)
    assert start.values in [s.values for s in starts] and start.values["inertia.motor"] == trial.values["inertia.motor"]
    assert training_ratio(predictor, res, null) < 0.1 and res.cost_test < 0.1 * null.cost_test
    assert "did not converge" in lines[0]
    # nothing to restart where the candidate has no parameter of its own
    assert loop._restarted_screen(predictor, "sticking_friction", stalled, trial, None, options, null,
                                  lines.append) == (stalled, trial)


def _screen_result(structure, cost_test, loss, capped=False):
    """A subset screen as ``_screen`` sees it: held-out cost, subset loss (the null started at 1)."""
    from types import SimpleNamespace

    from mjjoint.identify.fit import FitResult
    part = SimpleNamespace(loss=loss, start_loss=1.0, structure=structure)
    return FitResult(structure, float("nan"), cost_test, {}, {}, coarse_capped=capped, partial=part)


def _faked_screens(predictor, monkeypatch, fake_fit, fake_fits_from):
    """``_screen``'s fits replaced by ``fake_fit``/``fake_fits_from``, a finished screen's training
    cost its subset loss; returns the reference (the drive's base at a training cost of 1)."""
    import dataclasses

    from mjjoint.identify.fit import FitResult
    n = len(predictor.train)
    monkeypatch.setattr(loop, "fit", fake_fit)
    monkeypatch.setattr(loop, "fits_from", fake_fits_from)
    monkeypatch.setattr(loop, "finish", lambda pred, r: dataclasses.replace(
        r, partial=None, cost_train=r.partial.loss, train_costs=np.full(n, r.partial.loss)))
    return FitResult(Structure.create(BASE, DriveSpec(), 1.0), 1.0, 1.0, {}, {}, train_costs=np.ones(n))


def test_a_screen_another_start_took_below_the_model_still_descending_goes_on_over_all_windows(predictor,
                                                                                              monkeypatch):
    """The README route's play in its last round: from the catalogue's start its screen ends 1.53
    times above the model in training; another start ends at 0.56 times it, still descending at
    the iteration cap, so its subset point ranks nothing (held-out 1.14 times the model's): it
    goes on over all windows beside the best, where a stalled screen that gains as little
    would be left on the subset."""
    result = _screen_result

    def fake_fit(pred, s, names=None, **kw):
        if "friction_asymmetry" in s.effects:
            return result(s, 0.5, 0.5)  # the round's best
        if "input_offset" in s.effects:
            return result(s, 0.99, 1.53)  # stalled: above the model in training
        return result(s, 1.0, 1.0)  # the null

    restarted = []

    def fake_fits_from(pred, starts, names=None, **kw):
        restarted.append(len(starts))
        return [result(s, 0.98, 0.56 if i == 1 else 1.6, capped=True) for i, s in enumerate(starts)]

    ref = _faked_screens(predictor, monkeypatch, fake_fit, fake_fits_from)
    options = DiagnoseOptions(candidates=("friction_asymmetry", "input_offset"))

    lines = []

    def screen():
        return _screen(predictor, ref, {}, options, lines.append, ScreenClock(1), {}, set())
    _, finished, rest, above = screen()
    assert restarted == [loop.SCREEN_RESTARTS] and set(finished) == {"friction_asymmetry", "input_offset"}
    assert any(line.startswith("  screened input_offset on the subset") and "from another start" in line
               for line in lines)
    assert finished["input_offset"][1].cost_train == 0.56 and not above
    # still descending but above the model even so: it stays on the subset, listed as not converged
    monkeypatch.setattr(loop, "fits_from", lambda pred, starts, names=None, **kw: [
        result(s, 0.98, 1.2, capped=True) for s in starts])
    _, finished, rest, above = screen()
    assert set(finished) == {"friction_asymmetry"} and list(above) == ["input_offset"] and above["input_offset"] == 1.2


def test_a_candidate_is_fitted_from_other_starts_once_a_screen_whatever_its_variants(predictor, monkeypatch):
    """2SEP is screened from three starts (two lag gains, a soft contact's pre-sliding); a later
    start's other starts (the catalogue's, then the same seeded draws) are the first one's start
    and draws again, so where all stall only the first is restarted."""
    result = _screen_result

    def fake_fit(pred, s, names=None, **kw):
        return result(s, 0.99, 1.5) if "dynamic_friction" in s.effects else result(s, 1.0, 1.0)

    draws = []

    def fake_fits_from(pred, starts, names=None, **kw):
        draws.append([s.values["dynamic_friction.b"] for s in starts])
        return [result(s, 0.98, 1.3) for s in starts]

    ref = _faked_screens(predictor, monkeypatch, fake_fit, fake_fits_from)
    variants = loop._candidate_variants("dynamic_friction", {}, ref.structure)
    assert len(variants) == 3 and variants[0] == ({}, {})
    lines = []
    _screen(predictor, ref, {}, DiagnoseOptions(candidates=("dynamic_friction",)), lines.append, ScreenClock(1), {},
            set())
    assert sum("screened dynamic_friction on the subset" in line for line in lines) == 3
    # the draws a restart of the second variant would take: its own start, then the first's draws
    second = loop.with_candidate(ref.structure, "dynamic_friction", variants[1][0])
    from mjjoint.identify.fit import restart_points
    own = ["dynamic_friction.k", "dynamic_friction.b"]
    again = [s.values["dynamic_friction.b"]
             for s in restart_points(second, own, loop.SCREEN_RESTARTS, predictor.design.seed)]
    assert len(draws) == 1 and again[1:] == draws[0][:-1]
    assert again[0] == loop.with_candidate(ref.structure, "dynamic_friction").values["dynamic_friction.b"]


def test_an_unstable_screen_is_not_fitted_from_other_starts_and_the_verdict_says_it_was_unstable(predictor,
                                                                                               monkeypatch):
    """A screen whose prediction diverges at the finest step tried (KR300's rod, whose gear needs
    5 us) ends far above the model in training, but other starts of its own parameters cannot
    cure a step too coarse: it is not restarted, and the verdict lists it as unstable, not by a
    ratio of diverged costs."""
    from types import SimpleNamespace
    result = _screen_result

    def fake_fit(pred, s, names=None, **kw):
        return result(s, 1e6, 3e8) if "input_offset" in s.effects else result(s, 1.0, 1.0)

    restarted = []
    ref = _faked_screens(predictor, monkeypatch, fake_fit, lambda *a, **kw: restarted.append(a) or [])
    monkeypatch.setattr(loop, "_instability", lambda trial: ("the gear too stiff for the step", trial))
    unstable = {}
    _, _, _, above = _screen(predictor, ref, {}, DiagnoseOptions(candidates=("input_offset",)), lambda line: None,
                             ScreenClock(1), unstable, set())
    assert restarted == [] and unstable == {"input_offset": "the gear too stiff for the step"}
    assert above == {"input_offset": float("inf")}
    floor = SimpleNamespace(ratios=lambda nrmse: {"q": 10.0}, nrmse={"q": 0.01}, capped=(), scored=())
    text = loop._verdict([], ref, SimpleNamespace(nrmse_test={"q": 0.1}, cost_test=1.0), floor, False, {}, "", {},
                         above)
    assert "input_offset (its prediction unstable at the finest step tried" in text and "infx" not in text


def test_a_screen_asked_again_of_the_same_model_costs_no_rollout_and_gives_the_same_answer(predictor):
    """A round that leaves its model as it was (an effect refused as a stand-in) screens the same
    candidates against the same fit again: those subset fits and their finishing are made once
    per predictor, and a repeated screen returns the same results without a rollout."""
    base = fit(predictor, Structure.create(BASE, DriveSpec(), 1.0), max_iter=30)
    options = DiagnoseOptions(candidates=("input_offset", "friction_asymmetry"), screen_iter=4)

    def screen():
        return _screen(predictor, base, {}, options, lambda line: None, ScreenClock(1), {}, set())
    _, finished, rest, above = screen()
    spent = predictor.rollouts
    _, finished2, rest2, above2 = screen()
    assert predictor.rollouts == spent
    assert finished and {k: (c, r.structure.values) for k, (c, r) in finished2.items()} == {
        k: (c, r.structure.values) for k, (c, r) in finished.items()}
    assert {k: c for k, (c, _) in rest2.items()} == {k: c for k, (c, _) in rest.items()} and above2 == above
    # a copy each time: a caller's change to a result does not reach the next caller
    start = loop.with_candidate(base.structure, "input_offset")
    one = fit(predictor, start, max_iter=4, subset_only=True)
    cost, one.cost_test, one.seconds = one.cost_test, -1.0, -1.0
    again = fit(predictor, start, max_iter=4, subset_only=True)
    assert again.cost_test == cost and again.seconds > 0 and again.partial is one.partial
