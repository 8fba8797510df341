"""End to end: a recording of the independent plant, written as CSV, diagnosed as a user would,
scored by the out-of-regime criteria (docs/benchmark.md, "Out-of-regime set")."""
from __future__ import annotations

import pytest

from mjjoint.benchmark.independent.cases import CASES
from mjjoint.benchmark.independent.score import FAR, run_case
from mjjoint.diagnosis.loop import DiagnoseOptions

pytestmark = pytest.mark.long(3)


def test_a_hysteretic_gear_of_the_independent_plant_is_named(tmp_path):
    """A Bouc-Wen gear outside the development set's range (elastic share 0.6-0.8, x_u 4-8 mrad),
    5 s, two rival gear candidates, one round: the hysteresis is named and the verdict is not
    "explained" above the true sensors' floor."""
    options = DiagnoseOptions(candidates=("transmission_hysteresis", "backlash"), max_rounds=1, fit_iter=10,
                              screen_iter=6)
    score = run_case("boucwen_soft", 0, tmp_path, duration=5.0, options=options)
    assert (tmp_path / "recording.csv").exists()
    assert score.named == ["transmission_hysteresis"] and score.right and not score.false_additions
    assert score.nrmse_after < 0.5 * score.nrmse_before
    assert not score.explained_above_floor
    assert score.passed


def test_a_link_encoder_read_late_is_named_a_skew_not_a_hysteretic_gear(tmp_path):
    """A 1-3 ms timing skew between the encoders reads as a loop of the recorded torque against
    the recorded deflection: without the skew among the candidates, seed 0's default run named a
    Bouc-Wen gear (held-out cost -25 % at p 0.047). With both screened, the skew is named and the
    hysteresis is not."""
    options = DiagnoseOptions(candidates=("sensor_skew", "transmission_hysteresis"), max_rounds=1, fit_iter=10,
                              screen_iter=6)
    score = run_case("link_skew", 0, tmp_path, duration=5.0, options=options)
    assert score.named == ["sensor_skew"] and score.right and not score.false_additions, score.verdict
    assert score.nrmse_after < 0.2 * score.nrmse_before
    assert score.passed


@pytest.mark.slow
def test_a_skew_is_screened_with_the_gear_it_bent(tmp_path):
    """Seed 5's base fit takes its 1-3 ms skew for a gear damper too stiff for the plant's step:
    a skew screened against that gear held gained 1.5 % and nothing was named (delta 0.79 where
    the floor is 0.01). The skew frees the gear's stiffness and damping it stands in for
    (``Effect.stand_ins``), and the stand-in guard still asks its own term for the gain."""
    options = DiagnoseOptions(candidates=("sensor_skew", "input_delay", "transmission_hysteresis"), max_rounds=2,
                              fit_iter=10, screen_iter=6)
    score = run_case("link_skew", 5, tmp_path, duration=6.0, options=options)
    assert score.named == ["sensor_skew"] and score.right and not score.false_additions, score.verdict
    assert score.nrmse_after < 0.05 * score.nrmse_before
    assert score.passed


# The effects a late torque cell was taken for before the torque sensor's lag was screened.
LATE_CELL_RIVALS = ("link_flexibility", "input_delay", "sensor_skew")


@pytest.mark.parametrize("candidates", [
    pytest.param(("torque_skew", *LATE_CELL_RIVALS), id="against its rivals"),
    pytest.param(None, id="the default candidates", marks=pytest.mark.slow),
])
def test_a_torque_cell_behind_a_low_pass_is_named_a_late_torque_sensor(tmp_path, candidates):
    """A first-order low-pass of 0.5-2 ms on the torque cell: the recorded torque runs behind
    the recorded deflection, so the gear's recorded law gives energy back, which no physics of
    the joint does (``gear_law.law_energy``). That sign opens the default screen to the torque
    sensor's lag, screened otherwise only when asked (it would take a current loop's lag), and
    the late sensor is named alone: without it, seed 0 named a flexible rod and an input delay
    for it, seed 1 a link encoder skew, an input delay and a rod. In CI against those rivals
    (the sign's opening of the default list: ``tests/test_sensor_effects.py``); with the whole
    default list, slow."""
    lines = []
    options = DiagnoseOptions(candidates=candidates, max_rounds=1, fit_iter=10, screen_iter=6)
    score = run_case("torque_filter", 0, tmp_path, duration=5.0, options=options, progress=lines.append)
    assert any("gear law gives energy back" in line and "torque_skew" in line for line in lines)
    assert score.named == ["torque_skew"] and score.right and not score.false_additions, score.verdict
    assert "torque_skew [a sensor effect" in score.verdict  # the measurement, not the joint's physics
    assert score.passed


def test_a_current_loops_lag_is_named_a_lag_not_a_delay_and_a_friction_asymmetry(tmp_path):
    """Seed 0's 2-5 ms first-order current loop recorded without the torque column: with only the
    dead time to take it, the default run named the delay and, beside it, a friction level that
    depends on the direction (-12.4 % at p 0.0156), a false addition that took up what a dead
    time leaves of a lag. With the lag among the candidates it is named alone."""
    options = DiagnoseOptions(candidates=("input_lag", "input_delay", "friction_asymmetry", "input_offset"),
                              max_rounds=2, fit_iter=10, screen_iter=6)
    score = run_case("current_loop", 0, tmp_path, duration=6.0, options=options, torque=False)
    assert score.named == ["input_lag"] and score.right and not score.false_additions, score.verdict
    assert score.nrmse_after < 0.2 * score.nrmse_before
    assert score.passed


# The benchmark itself, with the criteria (slow: ~3 min a case on 2 cores).
@pytest.mark.slow
@pytest.mark.parametrize("name", list(CASES))
def test_out_of_regime_case(name, tmp_path):
    score = run_case(name, 0, tmp_path)
    assert not score.false_additions, score.verdict
    assert not score.explained_above_floor, f"explained at {score.worst} NRMSE {score.nrmse_after:.3g} > " \
                                            f"{FAR} x the true floor {score.true_floor:.3g}"
    assert score.right or score.honest or (not score.named and score.explained), score.verdict


@pytest.mark.slow
def test_cogging_at_a_real_period_is_named_by_its_generic_form(tmp_path):
    """Seed 9's cogging (3.41 cycles a motor revolution) shows in the prediction residuals only at
    the gear's resonance; the rotor's torque balance shows it at its period, and the generic form
    screened from there with every parameter free is named (docs/diagnosis.md, "The rotor's
    balance"; ~2 min)."""
    score = run_case("cogging", 9, tmp_path)
    assert score.named == ["motor_periodic_q"] and not score.false_additions, score.verdict
    assert score.nrmse_after < 0.05 * score.nrmse_before and score.passed


@pytest.mark.slow
def test_a_flexible_rods_damping_is_not_taken_for_a_hysteretic_gear(tmp_path):
    """Seed 2's lumped rod (2 % critical damping): with the rod's damping fixed at a guess the
    hysteretic gear took up the mode's decay and was named beside the rod (docs/diagnosis.md,
    "The loop"); fitted, the rod alone is named."""
    score = run_case("flexible_rod", 2, tmp_path)
    assert score.named == ["link_flexibility"] and not score.false_additions, score.verdict
    assert score.passed


@pytest.mark.slow
def test_a_rod_whose_screen_still_descends_at_a_finer_step_is_named(tmp_path):
    """Seed 4's lumped rod: the rigid base misses q at NRMSE 1.35; the rod's screen, taken to an
    eighth of the step, still descended at the subset phase's iteration cap at 1.1x the null's
    held-out cost and was left on the subset, so nothing was named. Finished over all windows it
    gains 58 % and the rod is named, q then within 0.15."""
    score = run_case("flexible_rod", 4, tmp_path)
    assert score.named == ["link_flexibility"] and not score.false_additions, score.verdict
    assert score.nrmse_after < 0.15 and score.passed


@pytest.mark.slow
def test_a_wide_play_is_not_taken_for_a_hardening_gear(tmp_path):
    """Seed 3's 1.3 mrad play: the base fit, whose gear never opens, bends the link's bearing and
    gravity around it, and a screen of the play that held them ended at 0.94 mrad while the
    hardening cubic was named (docs/benchmark.md, "Seed 3"); freed with it, the play is named."""
    score = run_case("backlash_wide", 3, tmp_path)
    assert score.named == ["backlash"] and not score.false_additions, score.verdict
    assert score.passed


@pytest.mark.slow
def test_without_a_torque_sensor_a_play_is_named_alone(tmp_path):
    """Seed 0's 1.1 mrad play recorded without the torque column: after the play, a viscous
    asymmetry of -2.5 % passed the acceptance rule (held-out cost -74.6 %), its fit having carried
    the other parameters to a better optimum; switched off at its own fit it lowers the held-out
    cost by 3 %, and the stand-in guard refuses it (docs/diagnosis.md, "Revising the search")."""
    score = run_case("backlash_wide", 0, tmp_path, torque=False)
    assert (tmp_path / "recording.csv").read_text().splitlines()[0] == "t,u,q,theta"
    assert score.named == ["backlash"] and not score.false_additions, score.verdict
    assert score.passed


@pytest.mark.slow
def test_a_base_its_step_cannot_hold_is_fitted_before_anything_is_screened(tmp_path):
    """Seed 1's big axis without the torque column: the base starts too stiff for the plant's
    step (its Coulomb slope against the motor's inertia). Fitted at the finer step its stability
    check asks for and carried back, it predicts delta to 0.044, and the play is the first and
    only effect named; from the diverged base a torque ripple was added first (-100 %)."""
    said: list[str] = []
    score = run_case("big_axis", 1, tmp_path, progress=said.append, torque=False)
    assert any("the base model's prediction diverged" in line for line in said), said[:5]
    assert score.nrmse_before < 0.1, score.nrmse_before
    assert [line.split()[1] for line in said if line.startswith("adding ")] == ["backlash"], score.verdict
    assert score.named == ["backlash"] and score.passed


@pytest.mark.slow
def test_point_to_point_moves_through_a_wide_play_add_no_skew(tmp_path):
    """Seed 0's moves: the base's regularised friction creeps through the rests (3.27 rad/s,
    its band 1) where the plant's holds. The exact sign's screen, opened by that sign, stood on
    the subset at the null's cost still descending and was left there; a skew of the link encoder
    was named instead (-17.8 %). Finished, the exact sign is the best candidate, nothing passes,
    and the verdict says the model does not explain the rests (~2.5 min)."""
    score = run_case("backlash_wide", 0, tmp_path, program="moves")
    assert not score.false_additions, score.verdict
    assert score.passed and "the rotor rests" in score.verdict
