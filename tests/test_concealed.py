"""Concealed-effect diagnosis on a shortened case set (the full set: scripts/concealed_benchmark.py).

A truth with one effect more than the base model is recorded in closed loop with quantised
sensors; the diagnosis sees only the CSV and the base effect list. The negative control has
nothing concealed: nothing may be added.
"""
from __future__ import annotations

import pytest

from mjjoint.benchmark.cases import CONCEALED
from mjjoint.benchmark.score import run_case
from mjjoint.diagnosis.loop import DiagnoseOptions

pytestmark = pytest.mark.long(1.5)

SHORT = 8.0  # [s] of recording: enough windows for a held-out quarter, fast enough for CI
# CI screens a fixed mix of candidates: the concealed one among confounders that act in the
# same places (reversals, small deflection, lag); the full benchmark screens every effect.
CI_CANDIDATES = ("backlash", "transmission_hysteresis", "stribeck_friction", "dynamic_friction", "input_delay")


@pytest.mark.parametrize("effect", ["backlash", "none"])
def test_concealed_effect_is_named_and_nothing_else(effect, tmp_path):
    score = run_case(effect, seed=1, folder=tmp_path, duration=SHORT,
                     options=DiagnoseOptions(candidates=CI_CANDIDATES, max_rounds=2))
    assert not score.false_additions, score
    if effect != "none":
        assert score.named, score
        assert score.nrmse_after < score.nrmse_before, score
        assert score.nrmse_truth < score.nrmse_before, score  # the truth lacks nothing the base lacks
        assert score.parameter_error is not None and score.parameter_error < 0.5, score


@pytest.mark.slow
@pytest.mark.parametrize("effect", CONCEALED)
def test_full_case_set(effect, tmp_path):
    score = run_case(effect, seed=2, folder=tmp_path, duration=20.0)
    assert score.passed, score


@pytest.mark.slow
def test_a_search_that_named_nothing_goes_on_from_the_bases_robust_estimate(tmp_path):
    """Seed 1's 2SEP truth: the least-squares base ends at a held-out cost of 0.21, held by the
    breakaways after dwells, and no screen gains on it; its robust estimate predicts at 0.00065,
    the search goes on from there and 2SEP is named, the final model predicting the held-out
    windows as the truth does. (Its lag gain B lands 22 % low: fitted from the truth itself,
    without the windows the recording leaves open, it lands there too; docs/benchmark.md.)"""
    score = run_case("dynamic_friction", seed=1, folder=tmp_path, duration=20.0)
    assert score.named and not score.false_additions, score
    assert score.nrmse_after <= 1.1 * score.nrmse_truth, score


@pytest.mark.slow
def test_the_converged_lag_is_named_from_two_starts(tmp_path):
    """Seed 0's 2SEP truth (base q NRMSE 1.12, truth 0.010): from the catalogue's lag gain alone
    the screen ended above the base, the lag's windup holding each breakaway in another valley of
    the cost; screened from a tenth of that gain too (``effects._lag_variants``), it is named
    within 20 %."""
    score = run_case("dynamic_friction", seed=0, folder=tmp_path, duration=20.0)
    assert score.passed, score


@pytest.mark.slow
def test_a_stalled_refit_leaves_no_room_for_a_stand_in(tmp_path):
    """Seed 3's backlash case: the least-squares refit with the play stalls at 10x the truth's
    held-out cost, and without the robust refit (DiagnoseOptions.robust_refit) the next round
    named nonlinear_stiffness for the rest (CHANGELOG.md, "Benchmark history", twelfth run). With
    it the fit still stalls at 0.0015; a Stribeck bump then passes with its ratio on the bound of
    none (fs = fc), and unless the play's model is refitted from where that fit left it (0.00011)
    a generic periodic friction is named two rounds later."""
    score = run_case("backlash", seed=3, folder=tmp_path, duration=20.0)
    assert score.passed and not score.false_additions, score


@pytest.mark.slow
def test_a_held_out_window_the_recording_leaves_open_does_not_hide_the_lag(tmp_path):
    """Seed 4's 2SEP truth: one held-out breakaway window, whose start the lead-ins leave open,
    holds 95 % of the truth's held-out cost; left out of every score (``diagnosis.open_starts``),
    2SEP is named with nothing beside it."""
    score = run_case("dynamic_friction", seed=4, folder=tmp_path, duration=20.0)
    assert score.passed, score
