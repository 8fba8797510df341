"""A material gain only the rank test refuses, looked at again on a second fold's held-out
windows (``diagnosis.loop.second_fold``): twice the windows, at half the level."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from mjjoint.diagnosis import loop
from mjjoint.identify.windows import WindowDesign, held_out


def test_the_folds_are_disjoint_shares_of_one_permutation_and_fold_0_is_the_split():
    design = WindowDesign(seed=3)
    folds = [held_out(design, 40, k) for k in range(4)]
    assert all(f.sum() == 10 for f in folds)
    assert np.array_equal(np.sum(folds, axis=0), np.ones(40))  # each window held out by exactly one
    assert np.array_equal(held_out(design, 40), folds[0])
    with pytest.raises(ValueError, match=r"fold=4 must lie in \[0, 3\] for 40 windows with 10 held out each"):
        held_out(design, 40, 4)


# Two folds of 10 held-out windows each; each "structure" is a name whose window costs are given.
class _Folded(SimpleNamespace):
    def refolded(self, fold):
        if self.other is None:
            raise ValueError("too few windows")
        return self.other


def _setting(monkeypatch, gain_first: np.ndarray, gain_second: np.ndarray, second: bool = True, open_=()):
    """``open_``: the second fold's held-out windows its start leaves open (``open_starts``)."""
    costs = {("first", "ref"): np.ones(10), ("first", "cand"): np.exp(-gain_first),
             ("second", "ref"): np.ones(10), ("second", "cand"): np.exp(-gain_second)}
    other = _Folded(name="second", test=np.arange(10), rollouts=0.0, other=None)
    pred = _Folded(name="first", test=np.arange(10), rollouts=0.0, other=other if second else None)

    def leave_out_open_starts(predictor, base, keep, say):
        assert predictor is other and base == "base" and keep == loop.MIN_HELDOUT
        predictor.test = np.setdiff1d(predictor.test, open_)
        if len(open_):
            say(f"held-out windows at {list(open_)} left out of every score")
        return list(open_)

    def fit(predictor, structure, max_iter):
        predictor.rollouts += 1.0
        return SimpleNamespace(structure=structure, cost_test=float(costs[predictor.name, structure].mean()))

    monkeypatch.setattr(loop, "fit", fit)
    monkeypatch.setattr(loop, "window_costs", lambda p, s, w: costs[p.name, s][w])
    monkeypatch.setattr(loop, "condition_mask", lambda p, e: (None, ""))
    monkeypatch.setattr(loop, "leave_out_open_starts", leave_out_open_starts)
    ref = SimpleNamespace(structure="ref", cost_test=1.0)
    choice = loop._Choice("input_delay", SimpleNamespace(structure="cand", cost_test=0.6), 0.4, [],
                          {"p": 0.042, "max_p": 0.025, "windows": "10 held-out windows", "n": 10},
                          ["paired p = 0.042 > 0.025"], True)
    said: list[str] = []
    return pred, loop.second_fold(pred, "base", ref, choice, loop.DiagnoseOptions(), said.append), choice, said


def test_a_gain_that_shows_on_the_second_fold_too_passes_at_half_the_level(monkeypatch):
    # 10 windows, 2 of them worse: p 0.042 alone; 8 of the second fold's 10 better
    first = np.array([0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, -0.35, -0.25])
    second = np.array([0.7, 0.6, 0.5, 0.45, 0.4, 0.35, 0.3, 0.25, -0.1, -0.05])
    pred, folded, _, said = _setting(monkeypatch, first, second)
    assert not folded.failed and not folded.only_inconsistent
    assert folded.consistency["n"] == 20 and folded.consistency["max_p"] == 0.0125
    assert folded.consistency["p"] <= 0.0125 and "two folds" in folded.consistency["windows"]
    assert pred.rollouts == 2.0  # the second fold's fits are counted
    assert "passes" in said[0]


def test_a_gain_the_second_fold_does_not_show_fails_on_both(monkeypatch):
    first = np.array([0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, -0.35, -0.25])
    second = np.random.default_rng(0).normal(0.0, 0.3, 10)
    _, folded, _, said = _setting(monkeypatch, first, second)
    assert folded.failed == [f"paired p = {folded.consistency['p']:.3f} > 0.0125"]
    assert folded.only_inconsistent and folded.consistency["n"] == 20
    assert "on 20 held-out windows of two folds (a longer recording" in loop.rejection(folded)
    assert "fails" in said[0]


def test_the_second_fold_scores_none_of_its_windows_the_recording_leaves_open(monkeypatch):
    """Its open windows (here the two where the candidate loses most) leave its score, as the
    split's do: 18 windows are judged, not 20."""
    first = np.array([0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, -0.35, -0.25])
    second = np.array([0.7, 0.6, 0.5, 0.45, 0.4, 0.35, 0.3, 0.25, -0.9, -0.8])
    _, scored, _, _ = _setting(monkeypatch, first, second)
    _, folded, _, said = _setting(monkeypatch, first, second, open_=(8, 9))
    assert scored.consistency["n"] == 20 and folded.consistency["n"] == 18
    assert folded.consistency["p"] < scored.consistency["p"]
    assert said[0] == "  second fold: held-out windows at [8, 9] left out of every score"
    assert "passes" in said[1]


def test_a_recording_too_short_for_a_second_fold_keeps_the_choice(monkeypatch):
    _, folded, choice, said = _setting(monkeypatch, np.ones(10), np.ones(10), second=False)
    assert folded is choice and not said


def test_the_second_fold_adds_at_most_half_the_level_to_false_additions():
    """Null reductions (symmetric about zero) on both folds: where the first look refused at
    0.025, the look at 0.0125 on both folds names at most 1.25 % of all draws."""
    rng = np.random.default_rng(11)
    named = 0
    draws = 4000
    for _ in range(draws):
        d = rng.standard_t(3, size=20)
        if loop.consistency_record(d[:10], None, "")["p"] > 0.025:
            named += loop.consistency_record(d, None, "")["p"] <= 0.0125
    assert named / draws <= 0.0125 * 1.2, named / draws
