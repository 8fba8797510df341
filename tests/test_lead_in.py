"""2SEP states of windows that start at rest or just after a reversal, from a simulated lead-in
(Predictor._start_states).

At rest the motor chatters below one encoder count and 2SEP's lag state winds up; after a
reversal the pre-sliding force depends on where the motor turned to within a fraction of a count.
The recording cannot show either, the model's own simulation of the motion can.
"""
from __future__ import annotations

import numpy as np
import pytest

from mjjoint.benchmark.cases import GEAR_RATIO, NOMINAL, make_case
from mjjoint.diagnosis.open_starts import leave_out_open_starts, with_lag
from mjjoint.rehearse import LabProgram, record
from mjjoint.identify.fit import fit, window_costs
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import (REVERSAL_BAND, UNDETERMINED, Measured, Predictor, WindowDesign, held_out,
                                     lead_samples, transient_lead)
from mjjoint.recordings import Recording

RATE = 1000.0


def _leads(qd, starts, lead=1.0, joins=()):
    """Lead-ins on a bare velocity record, as a Predictor asks for them (noise 1e-4 rad: moving
    above 0.3 rad/s)."""
    return lead_samples(np.asarray(qd, float), REVERSAL_BAND * 1e-4 * RATE, starts, joins, int(round(lead * RATE)))


def test_a_resting_start_leads_in_from_the_last_motion_within_the_cap_and_its_log():
    qd = np.zeros(5000)
    qd[:1000] = 2.0                       # moving, then at rest from sample 1000
    qd[3000:3100] = -0.5                  # a short move
    assert REVERSAL_BAND * 1e-4 * RATE < 0.5
    leads = _leads(qd, [500, 1000, 1400, 2500, 3050, 3400])
    assert leads.tolist() == [0, 1, 401, 1000, 0, 301]  # 2500: capped at 1 s; 3050: moving
    assert _leads(qd, [1400], lead=0.2).tolist() == [200]
    assert _leads(qd, [1400], lead=0.0).tolist() == [0]
    assert _leads(qd, [1400, 1250], joins=[1200]).tolist() == [200, 50]  # not across a join
    assert _leads(qd, [1200], joins=[1200]).tolist() == [0]


def test_a_start_just_after_a_slow_sample_leads_in_from_before_it():
    """``windows.TRANSIENT``'s rule: a moving start within ``within`` samples of a sample at most ``speed`` leads in
    from the last sample faster than ``speed`` before that one; not across a join, not beyond the cap."""
    qd = np.full(3000, 5.0)
    qd[1000:1010] = np.linspace(0.5, -0.5, 10)   # a reversal, slow for 10 samples
    qd[1010:] = -5.0
    speed = 1.0
    args = (speed, np.array([900, 1005, 1015, 1030, 1060]), (), 1000)
    # slow from 1000 to 1009, the last faster sample 999; 1005 is slow itself, 1015 and 1030 come
    # 6 and 21 samples after the last slow one
    assert transient_lead(qd, *args, within=20).tolist() == [0, 6, 16, 0, 0]
    assert transient_lead(qd, *args, within=60).tolist() == [0, 6, 16, 31, 61]
    assert transient_lead(qd, speed, np.array([1015]), (1010,), 1000, 20).tolist() == [0]   # slow before the join
    assert transient_lead(qd, speed, np.array([1015]), (1003,), 1000, 20).tolist() == [12]  # lead-in from the join
    assert transient_lead(qd, speed, np.array([1015]), (), 5, 20).tolist() == [5]


@pytest.fixture(scope="module")
def lab():
    """A 10 s closed-loop lab recording of seed 0's 2SEP truth, and its true structure."""
    case = make_case("dynamic_friction", 0)
    cols = record(*case.truth.model_params(), LabProgram(duration=10.0, seed=0))
    return case.truth, Measured.from_recording(Recording(gear_ratio=GEAR_RATIO, meta={}, **cols), GEAR_RATIO)


def _static(truth: Structure) -> Structure:
    """The truth without 2SEP: its other effects at their values."""
    return Structure.create(tuple(e for e in truth.effects if e != "dynamic_friction"), truth.nominal,
                            truth.gear_ratio, {k: v for k, v in truth.values.items() if "dynamic_friction" not in k})


def test_only_2sep_models_and_only_their_lead_in_windows_are_changed(lab):
    truth, measured = lab
    static = _static(truth)
    without, with_lead = (Predictor(measured, WindowDesign(seed=0, lead=lead)) for lead in (0.0, 1.0))
    for a, b in zip(without.predict([static]), with_lead.predict([static])):
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])
    (a,), (b,) = without.predict([truth]), with_lead.predict([truth])
    led = with_lead.lead_samples > 0
    resting = led & with_lead.resting
    assert 0 < resting.sum() < led.sum() < len(led)  # some lead in from a transient
    np.testing.assert_array_equal(a["q"][~led], b["q"][~led])
    assert np.all(np.any(a["q"][resting] != b["q"][resting], axis=1))


def test_the_undetermined_windows_are_breakaways_from_rest_of_a_2sep_model(lab):
    """A window whose prediction depends on where the lead-in through the stop before it starts
    (``Predictor.undetermined``) starts at rest and breaks away within it; a window at rest
    throughout, or one without 2SEP, is never undetermined. The truth's own cost there is far
    above its cost on the windows that start moving: the states the recording does not fix."""
    truth, measured = lab
    pred = Predictor(measured, WindowDesign(seed=0))
    every = np.arange(len(pred.starts))
    static = _static(truth)
    before = pred.rollouts
    assert pred.undetermined(static, every).size == 0 and pred.rollouts == before  # nothing rolled out
    open_ = pred.undetermined(truth, every)
    assert open_.size > 0
    moves = np.abs(measured.qd[pred.samples]).max(axis=1) > measured.moving_speed
    assert np.all(pred.lead_samples[open_] > 0) and np.all(moves[open_])
    resting = pred.resting
    assert not set(open_) & set(np.flatnonzero(resting & ~moves))
    spread = pred.lead_in_spread(truth, open_)
    assert np.all(spread > UNDETERMINED)
    costs = window_costs(pred, truth, every)
    assert costs[open_].min() > 10 * np.median(costs[~resting])


def test_a_window_is_predicted_alike_whatever_windows_come_with_it(lab):
    truth, measured = lab
    pred = Predictor(measured, WindowDesign(seed=0))
    resting = np.flatnonzero(pred.lead_samples > 0)
    (every,) = pred.predict([truth])
    (some,) = pred.predict([truth], resting[::3])
    for k in every:
        np.testing.assert_array_equal(every[k][resting[::3]], some[k])


def test_a_recording_that_starts_at_rest_starts_with_the_friction_unloaded(lab):
    """The lab recording starts at rest (a fresh model, 2SEP states 0); its first velocity sample
    is noise, which must not put the history's start on a sliding branch."""
    truth, measured = lab
    pred = Predictor(measured, WindowDesign(seed=0))
    assert measured.qd[0] != 0.0
    assert pred._motion(np.array([0]), path=True)["w"][0] == 0.0


def test_the_lag_gain_is_recovered_with_the_lead_in(lab):
    """Fitted from the truth with every parameter free: B within 10 % with the resting windows'
    2SEP states from a lead-in that starts where the motor last moved. (Without it, from the
    history along the measured path, B lands at 0.28 of the truth: a stop's motion under an
    encoder count sets the lag's windup at rest, and the measured path does not hold it.)"""
    truth, measured = lab
    pred = Predictor(measured, WindowDesign(seed=0, lead=1.0))
    f = fit(pred, truth)
    b = f.structure.values["dynamic_friction.b"] / truth.values["dynamic_friction.b"]
    assert abs(b - 1) < 0.1, b
    # resting windows the fitted model leaves open are left out of its fit; none it kept is open
    resting = set(np.flatnonzero(pred.resting).tolist()) & set(pred.train.tolist())
    assert f.left_out and set(f.left_out) <= resting
    assert pred.undetermined(f.structure, np.setdiff1d(pred.train, f.left_out)).size == 0
    assert len(f.train_costs) == len(pred.train)


def test_the_lag_gain_is_recovered_where_windows_start_after_reversals():
    """The 20 s lab recording of seed 1's 2SEP truth, fitted from the truth: B within 10 %. Its
    windows that start within their warmup of a reversal take 2SEP's states from a lead-in
    (TRANSIENT); run along the measured angle instead, B lands at 0.78 of the truth."""
    case = make_case("dynamic_friction", 1)
    cols = record(*case.truth.model_params(), LabProgram(duration=20.0, seed=1))
    measured = Measured.from_recording(Recording(gear_ratio=GEAR_RATIO, meta={}, **cols), GEAR_RATIO)
    pred = Predictor(measured, WindowDesign(seed=1))
    transient = (pred.lead_samples > 0) & ~pred.resting
    assert transient.any()
    assert np.all(np.abs(measured.qd[pred.starts[transient]]) > measured.moving_speed)
    f = fit(pred, case.truth, max_iter=30)
    b = f.structure.values["dynamic_friction.b"] / case.truth.values["dynamic_friction.b"]
    assert abs(b - 1) < 0.1, b


def test_a_flexible_link_keeps_the_history_after_reversals():
    """On a flexible link a lead-in starts with the rod straight, and through a transient's short
    lead-in its ringing would set the 2SEP states: there only resting windows lead in."""
    truth = make_case("dynamic_friction", 0).truth.with_effect("link_flexibility", {"link_flexibility.ei": 300.0})
    cols = record(*truth.model_params(), LabProgram(duration=6.0, seed=0))
    pred = Predictor(Measured.from_recording(Recording(gear_ratio=GEAR_RATIO, meta={}, **cols), GEAR_RATIO),
                     WindowDesign(seed=0))
    transient = (pred.lead_samples > 0) & ~pred.resting
    assert transient.any() and (pred.resting & (pred.lead_samples > 0)).any()
    resting_only = Predictor(pred.m, WindowDesign(seed=0))
    resting_only.__dict__["lead_samples"] = np.where(pred.resting, pred.lead_samples, 0)
    (a,), (b,) = pred.predict([truth]), resting_only.predict([truth])
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])


def test_the_held_out_windows_the_lag_leaves_open_are_left_out_of_every_score(lab):
    """``diagnosis.open_starts``: the held-out windows the base with 2SEP at its catalogue values
    leaves open leave ``test`` (not ``train``), and the truth's own cost there is what no start
    the recording gives can fix; a second fold's leave its own score. Held-out sets without such
    a window stay as they were."""
    truth, measured = lab
    base = Structure.create(make_case("dynamic_friction", 0).base_effects, NOMINAL, GEAR_RATIO)
    lagged = with_lag(base)
    every = Predictor(measured, WindowDesign(seed=0))
    open_ = every.undetermined(lagged, np.arange(len(every.starts)))
    assert open_.size > 0
    n = len(every.starts)
    meets = {s: np.isin(open_, np.flatnonzero(held_out(WindowDesign(seed=s), n))).any() for s in range(40)}
    clear = [s for s in meets if not meets[s]]
    # a split and a second fold that each hold an open window
    holds = [s for s in meets if meets[s] and np.isin(open_, np.flatnonzero(held_out(WindowDesign(seed=s), n, 1))).any()]
    assert holds and clear

    pred = Predictor(measured, WindowDesign(seed=holds[0]))
    test, train = pred.test, pred.train
    left = np.intersect1d(open_, test)
    said = []
    assert leave_out_open_starts(pred, base, len(test) - len(left) + 1, said.append) == []  # too few would remain
    np.testing.assert_array_equal(pred.test, test)
    assert "kept in the score" in said[-1]
    starts = leave_out_open_starts(pred, base, len(test) - len(left), said.append)
    assert starts == [round(float(measured.t[pred.starts[w]]), 4) for w in left] and "left out" in said[-1]
    assert leave_out_open_starts(pred, base, len(test) - len(left), said.append) == starts  # the same once more
    np.testing.assert_array_equal(pred.test, np.setdiff1d(test, left))
    np.testing.assert_array_equal(pred.train, train)
    assert not pred.scored_holdout[left].any() and pred.holdout[left].all()
    costs = window_costs(pred, truth, test)
    assert costs[np.isin(test, left)].min() > 10 * np.median(costs[~np.isin(test, left)])

    other = pred.refolded(1)  # the second fold takes nothing of the split's but decides its own
    fold = np.flatnonzero(held_out(pred.design, n, 1))
    np.testing.assert_array_equal(other.test, fold)
    left = np.intersect1d(open_, fold)
    assert leave_out_open_starts(other, base, 5, said.append) == [round(float(measured.t[pred.starts[w]]), 4)
                                                                 for w in left]
    np.testing.assert_array_equal(other.test, np.setdiff1d(fold, left))
    np.testing.assert_array_equal(pred.test, np.setdiff1d(test, np.intersect1d(open_, test)))

    pred = Predictor(measured, WindowDesign(seed=clear[0]))
    test = pred.test
    assert leave_out_open_starts(pred, base, 5, said.append) == []
    np.testing.assert_array_equal(pred.test, test)


def test_the_lag_is_added_with_what_it_needs_or_not_at_all():
    minimal = Structure.create((), NOMINAL, GEAR_RATIO)
    assert with_lag(minimal).effects == ("coulomb_friction", "dynamic_friction")
    sticking = Structure.create(("coulomb_friction", "sticking_friction"), NOMINAL, GEAR_RATIO)
    assert with_lag(sticking) is None
    lagged = with_lag(minimal)
    assert with_lag(lagged) is lagged
