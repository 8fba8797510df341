"""``mjjoint design``: experiments that separate two rival explanations, and the decision after.

Fast properties of the parts (families within the torque limit by construction, antithetic
parameter draws, the criterion's noise scaling and zero for identical rivals, an input's noise
floor growing with its motion, closed-loop references tracked under a saturated controller, the
design beating the same-length default chirp on the criterion), the CLI's one-line errors, one
short end-to-end case (a truth with an input offset, rivals fitted to a one-way recording that
ties them, the designed experiment rehearsed, recorded from the truth and decided) and, marked
slow, the CLI end to end and the acceptance benchmark.
"""
from __future__ import annotations

import math

import json

import numpy as np
import pytest

from mjjoint.benchmark.design_cases import PAIRS, fit_rivals, make_design_case, run_case, tie
from mjjoint.cli import main
from mjjoint.design import Limits, Rival, SearchOptions
from mjjoint.design.criterion import discrimination
from mjjoint.design.families import FAMILIES, programme
from mjjoint.design.optimise import Evaluator
from mjjoint.design.record import record
from mjjoint.excitation import FromFile
from mjjoint.recordings import write_recording

pytestmark = pytest.mark.long(1)


def test_every_family_keeps_the_torque_limit_by_construction():
    limits = Limits(max_torque=0.07, duration=3.0)
    points = np.random.default_rng(0).uniform(0, 1, (25, 3))
    for family in FAMILIES:
        for p in np.vstack([points, np.zeros(3), np.ones(3)]):
            _, u = programme(family, p, limits)
            assert len(u) == limits.samples and np.all(np.isfinite(u))
            assert np.max(np.abs(u)) <= limits.max_torque * (1 + 1e-12), (family, p)


@pytest.mark.parametrize("field,value", [("max_torque", 0.0), ("max_speed", -1.0), ("duration", 1.0),
                                         ("angle_range", float("nan"))])
def test_limits_refuse_bad_values_naming_them(field, value):
    with pytest.raises(ValueError, match=field):
        Limits(**{field: value})


def test_limits_refuse_unknown_signals():
    with pytest.raises(ValueError, match="subset of q,theta,tau"):
        Limits(signals=("q", "current"))


def test_parameter_draws_are_antithetic_about_the_fit_and_inside_bounds():
    case = make_design_case("backlash_hysteresis", 1, 0)
    rival = Rival("transmission_hysteresis", case.truth,
                  {"transmission_hysteresis.mu": (0.3, 0.5), "transmission_hysteresis.x_u": (1e-3, 4e-3)})
    names = rival.drawn
    assert names == ("transmission_hysteresis.mu", "transmission_hysteresis.x_u")
    draws = np.array([s.vector(names) for s in rival.draws(6, seed=3)])
    assert np.allclose(draws.mean(axis=0), case.truth.vector(names))  # antithetic pairs
    lo, hi = case.truth.bounds(names)
    assert np.all(draws >= lo) and np.all(draws <= hi)
    se = rival.standard_errors()
    assert se[0] == pytest.approx(0.2 / (2 * 1.959964)) and se[1] == pytest.approx(np.log(4) / (2 * 1.959964))


@pytest.fixture(scope="module")
def pair_evaluator():
    """Rivals offset vs asymmetry at hand-set values (no fit), no draws: the criterion alone."""
    case = make_design_case("offset_asymmetry", 0, 0)
    a = Rival("input_offset", case.base.with_effect("input_offset", {"input_offset.offset": 0.012}))
    b = Rival("friction_asymmetry", case.base.with_effect("friction_asymmetry", {"friction_asymmetry.ratio": -0.4}))
    limits = Limits(max_torque=0.1, duration=3.0)
    noise = {"q": 1e-4, "delta": 3e-6, "tau": 0.05}
    return a, b, limits, noise


def test_the_criterion_is_zero_between_identical_rivals_and_scales_as_one_over_noise_variance(pair_evaluator):
    a, b, limits, noise = pair_evaluator
    opts = SearchOptions(draws=0)
    twin = Rival("input_offset", a.structure)
    point = [0.2, 0.5, 0.4]  # within the limits: an input past one is not scored
    same = Evaluator((a, twin), noise, limits, opts).point("dwell_reverse", point)
    assert same.feasible and same.score == 0.0
    ev = Evaluator((a, b), noise, limits, opts)
    c1 = ev.point("dwell_reverse", point)
    ws = list(c1.windowed)
    doubled = {k: 2 * v for k, v in noise.items()}
    assert c1.score > 0
    assert discrimination(ws, doubled, limits.signals) == pytest.approx(c1.score / 4, rel=1e-9)


def test_design_cli_refuses_bad_input_in_one_line(tmp_path, capsys):
    rec = tmp_path / "rec.csv"
    # a joint that moves (one at rest is refused before the options are looked at) and deflects
    # (a theta of exactly q/N is one encoder's, whose deflection is not measured)
    rec.write_text("t,u,q,theta\n" + "".join(f"{k / 1000},{0.1 * math.sin(k / 159)},{10 * math.sin(k / 159)},"
                                              f"{math.sin(k / 159) / 16 + 1e-4 * math.sin(k / 37)}\n"
                                              for k in range(3000)))
    cases = [(["--rivals", "backlash"], "exactly two"),
             (["--rivals", "backlash,nonsense"], "unknown effect 'nonsense'"),
             (["--rivals", "backlash,transmission_hysteresis", "--max-torque", "-1"], "max_torque=-1"),
             (["--rivals", "backlash,transmission_hysteresis", "--signals", "q,current"], "comma list of q,theta,tau"),
             (["--diagnosis", str(tmp_path)], "no diagnosis.json"),
             (["--rivals", "backlash,transmission_hysteresis", "--on", "link"], "--on needs --controller"),
             (["--rivals", "backlash,transmission_hysteresis", "--rehearse", "-1"], "rehearse=-1"),
             (["--rivals", "backlash,transmission_hysteresis", "--base", "linear_stiffness"], "no noise floor for tau"),
             (["--base", "linear_stiffness,backlash", "--rivals", "backlash,transmission_hysteresis",
               "--signals", "q,theta"],
              "already in the starting model")]
    for extra, message in cases:
        code = main(["design", str(rec), "--gear-ratio", "160", "--out", str(tmp_path / "out"), *extra])
        err = capsys.readouterr().err
        assert code == 2 and err.startswith("mjjoint: error:") and message in err, (extra, err)
        assert len(err.strip().splitlines()) == 1
        assert not (tmp_path / "out").exists()


def test_short_case_designs_within_limits_beats_the_chirp_and_names_the_truth():
    """offset vs asymmetry, truth with an input offset: one draw, a small search, a reference for
    the default PD (as the acceptance benchmark). One Sobol point of two families: the chirp is
    the best they find, so the search goes on from it (``SearchOptions.push``)."""
    from mjjoint.rehearse import Controller
    case = make_design_case("offset_asymmetry", 0, 1, duration=5.0)
    limits = Limits(max_torque=0.2, max_speed=80.0, angle_range=1.0, duration=6.0)
    options = SearchOptions(starts=1, refine=0, draws=2, rehearse=1, rehearse_iter=3,
                            families=("chirp", "dwell_reverse"))
    result = run_case(case, limits, options, max_iter=6, loop=Controller())
    assert result.get("error") is None and result["usage"] <= 1.0 and not result["truth_violations"]
    assert result["rehearsed"] > 0 and result["llr"] > 0  # the rehearsal and the decision both name the truth
    # The chirp at the largest amplitude within the limits; none may exist (the offset alone can
    # drive the link out of range): then it is no comparison, and says so.
    if result["chirp_feasible"]:
        assert result["D"] > (1 + options.min_gain) * result["D_chirp"] and result["unbeaten"] is None
    else:
        assert result["chirp_usage"] > 1
    assert result["winner"] == "input_offset"


@pytest.mark.slow
def test_design_cli_end_to_end_writes_a_runnable_experiment_and_decides(tmp_path, capsys):
    case = make_design_case("offset_asymmetry", 1, 2, duration=5.0)
    old = tmp_path / "old.csv"
    write_recording(old, record(case.truth, case.original, 1000.0))
    base = ",".join(case.base.effects)
    out = tmp_path / "design"
    rivals = ",".join(PAIRS["offset_asymmetry"][0])
    args = ["design", str(old), "--gear-ratio", "160", "--base", base, "--rivals", rivals,
            "--duration", "6", "--max-speed", "80", "--angle-range", "1", "--starts", "2", "--refine", "2",
            "--draws", "2", "--max-iter", "8", "--rehearse", "1"]
    assert main([*args, "--out", str(out)]) == 0
    data = json.loads((out / "design.json").read_text())
    assert data["discrimination_nats"] > 0 and max(data["limit_usage"].values()) <= 1.0
    for name in ("experiment.csv", "responses.png", "responses.rrd", "index.html", "run.json"):
        assert (out / name).stat().st_size > 0
    exp = FromFile(out / "experiment.csv")
    sim_csv = tmp_path / "run.csv"
    assert main(["simulate", "--excitation", "file", "--file", str(out / "experiment.csv"), "--csv", str(sim_csv)]) == 0
    u = exp.sample(1000.0, 6.0)
    assert np.max(np.abs(u)) <= 0.2
    new = tmp_path / "new.csv"
    write_recording(new, record(case.truth, u, 1000.0))
    assert main([*args, "--decide", str(new), "--out", str(tmp_path / "decide")]) == 0
    decision = json.loads((tmp_path / "decide" / "decision.json").read_text())
    assert decision["winner"] == "friction_asymmetry"


@pytest.mark.slow
def test_design_cli_closed_loop_exports_a_reference_the_loop_runs(tmp_path, capsys):
    case = make_design_case("offset_asymmetry", 1, 2, duration=5.0)
    old = tmp_path / "old.csv"
    write_recording(old, record(case.truth, case.original, 1000.0))
    out = tmp_path / "design"
    args = ["design", str(old), "--gear-ratio", "160", "--base", ",".join(case.base.effects), "--rivals",
            ",".join(PAIRS["offset_asymmetry"][0]), "--duration", "5", "--max-speed", "80", "--angle-range", "1",
            "--starts", "1", "--refine", "0", "--draws", "0", "--rehearse", "1", "--max-iter", "5",
            "--controller", "pd", "--out", str(out)]
    assert main(args) == 0
    data = json.loads((out / "design.json").read_text())
    assert data["experiment"]["loop"] == "closed" and data["experiment"]["controller"]["u_max"] == 0.2
    assert max(data["limit_usage"].values()) <= 1.0 and len(data["rehearsed"]) == 1
    assert "--reference" in capsys.readouterr().out
    assert main(["simulate", "--controller", "pd", "--limit", "0.2", "--reference", str(out / "experiment.csv"),
                 "--duration", "5", "--csv", str(tmp_path / "new.csv")]) == 0


def test_design_writes_the_experiment_the_simulator_reads_and_never_one_past_a_limit(pair_evaluator, tmp_path):
    from mjjoint.design import design
    from mjjoint.design.export import separated, write_design
    from mjjoint.design.limits import violations
    from mjjoint.report.output import OutputDir
    a, b, limits, noise = pair_evaluator
    d = design((a, b), noise, limits, SearchOptions(starts=2, refine=0, draws=0, rehearse=0,
                                                    families=("slow_reversal",)))
    assert all(not violations(tr, limits, "rival") for tr in d.best.traces)
    assert all(u <= 1.0 for f, p, s, u in d.evaluated if s == d.best.score and f == d.best.family)
    # one row per input run: the reference chirp's chosen amplitude, scored after it was run, once
    chirps = [(s, u) for f, p, s, u in d.evaluated if f == "default chirp" and u == d.reference.usage]
    assert chirps == [(d.reference.score, d.reference.usage)]
    out = OutputDir(tmp_path / "design")
    with out.staged() as folder:
        data = write_design(folder, d, {"command": "design"})
    assert data["discrimination_nats"] == d.best.score > 0
    # The decision compares the held-out windows only; not rehearsed: no rehearsed figure.
    assert 0 < data["discrimination_heldout_nats"] < d.best.score and data["rehearsed_ratio_nats"] is None
    exp = FromFile(out.path / "experiment.csv")
    assert np.array_equal(exp.sample(limits.rate, limits.duration), d.best.u)
    marks = separated(d)
    assert all(m.shape == d.best.u.shape for m in marks.values()) and any(m.any() for m in marks.values())
    assert json.loads((out.path / "run.json").read_text())["files"] == sorted(
        ["design.json", "experiment.csv", "index.html", "responses.png", "responses.rrd", "run.json"])


def test_rivals_from_a_diagnosis_are_its_named_effect_and_first_indistinguishable_one(tmp_path):
    from mjjoint.assets import ArmSpec
    from mjjoint.cli.design import rivals_from_diagnosis
    final = {"effects": ["coulomb_friction", "linear_stiffness", "input_offset"],
             "parameters": {"coulomb_friction.fc": 0.04, "linear_stiffness.k1": 9000.0, "input_offset.offset": 0.01},
             "settings": {}}
    steps = [{"effect": "input_offset", "indistinguishable_from": ["friction_asymmetry", "viscous_asymmetry"]}]
    (tmp_path / "diagnosis.json").write_text(json.dumps({"final_model": final, "steps": steps}))
    base, pair = rivals_from_diagnosis(tmp_path, ArmSpec(segments=0), 160.0)
    assert pair == ("input_offset", "friction_asymmetry")
    assert base.effects == ("coulomb_friction", "linear_stiffness")
    assert base.values["coulomb_friction.fc"] == 0.04 and "input_offset.offset" not in base.values


@pytest.mark.parametrize("text, message", [
    ("[1]", "'list' object has no attribute"),
    ('{"steps": [{"effect": "input_offset", "indistinguishable_from": ["viscous_asymmetry"]}]}', "no 'final_model'"),
    ('{"steps": ["x"]}', "'str' object has no attribute"),
    ("{", "Expecting property name"),
])
def test_a_diagnosis_json_that_is_not_one_is_refused_in_one_line(tmp_path, text, message):
    from mjjoint.assets import ArmSpec
    from mjjoint.cli.design import rivals_from_diagnosis
    from mjjoint.cli.errors import CliError
    (tmp_path / "diagnosis.json").write_text(text)
    with pytest.raises(CliError, match="not a diagnosis.json as 'mjjoint diagnose' writes it") as info:
        rivals_from_diagnosis(tmp_path, ArmSpec(segments=0), 160.0)
    assert message in str(info.value) and str(tmp_path) in str(info.value) and "\n" not in str(info.value)


def test_a_diagnosis_without_a_tie_has_nothing_to_separate(tmp_path):
    from mjjoint.assets import ArmSpec
    from mjjoint.cli.design import rivals_from_diagnosis
    from mjjoint.cli.errors import CliError
    (tmp_path / "diagnosis.json").write_text('{"steps": [{"effect": "backlash"}], "final_model": {}}')
    with pytest.raises(CliError, match="no step names an indistinguishable rival; nothing to separate"):
        rivals_from_diagnosis(tmp_path, ArmSpec(segments=0), 160.0)


@pytest.mark.slow
def test_benchmark_names_the_true_effect_in_nine_tenths_of_tied_draws_within_limits():
    """The acceptance benchmark (``scripts/bench_design.py --seeds 2 --starts 2 --refine 3
    --draws 2 --max-iter 6 --duration 6 --loop --tied-only``): of the draws whose original
    recording tied, >= 90 % named; no rival's or truth's run of a designed reference past a limit."""
    from mjjoint.rehearse import Controller
    limits = Limits(max_torque=0.2, max_speed=80.0, angle_range=1.0, duration=6.0)
    options = SearchOptions(starts=2, refine=3, draws=2)
    results = []
    for pair in PAIRS:
        for seed in (0, 1):
            for side in (0, 1):
                case = make_design_case(pair, side, seed, 6.0)
                fitted = fit_rivals(case, 6)
                if tie(fitted[1]) <= 0.05:  # only a draw whose original tied is in question
                    results.append(run_case(case, limits, options, max_iter=6, loop=Controller(), fitted=fitted))
    assert len(results) >= 8
    assert all(not r.get("truth_violations") and r.get("usage", 0) <= 1 for r in results)
    assert sum(r["correct"] for r in results) >= 0.9 * len(results)


def test_the_backlash_truths_original_recording_ties_the_rivals():
    """The benchmark's premise on its hardest pair: a play of a few encoder counts under a small
    slow sine is fitted as well by a soft hysteretic gear (held-out costs within 5 %)."""
    case = make_design_case("backlash_hysteresis", 0, 2, 6.0)
    assert case.truth.values["backlash.width"] < 3e-5
    rivals, found = fit_rivals(case, 6)
    assert tie(found) <= 0.05
    assert [r.effect for r in rivals] == ["backlash", "transmission_hysteresis"]


def test_the_designed_input_beats_a_same_length_default_chirp_on_the_criterion(pair_evaluator):
    """Hand-set rivals, fixed noise: the search's best against the default chirp (30 -> 1 Hz) at
    the largest amplitude that keeps both rivals within the same limits, same length."""
    from mjjoint.design import design
    a, b, limits, noise = pair_evaluator
    d = design((a, b), noise, limits, SearchOptions(starts=2, refine=4, draws=0, rehearse=0,
                                                    families=("chirp", "dwell_reverse")))
    assert d.reference.feasible and len(d.reference.u) == len(d.best.u)
    # The search starts from the default chirp too (a point of the chirp family): it can only gain.
    assert any(f == "chirp" and s == pytest.approx(d.reference.score, rel=1e-6) for f, p, s, u in d.evaluated)
    assert d.best.score > (1 + SearchOptions().min_gain) * d.reference.score > 0 and d.best.usage <= 1.0
    assert d.beats_reference and d.unbeaten is None


def test_where_the_chirp_is_the_best_found_the_search_goes_on_from_it_until_it_beats_it(pair_evaluator):
    """One Sobol point of the chirp family and the default chirp's own point: the chirp is the
    best found. The search then goes on from it (within the same limits and margin) until D
    beats the chirp's by the stated gain; without that budget the design is the chirp, and it
    says which limit the chirp sits against."""
    from mjjoint.design import design
    a, b, limits, noise = pair_evaluator
    options = SearchOptions(starts=1, refine=0, draws=0, rehearse=0, families=("chirp",))
    d = design((a, b), noise, limits, options)
    assert d.best.score > (1 + options.min_gain) * d.reference.score > 0
    assert d.best.usage <= 1.0 and d.beats_reference and d.unbeaten is None
    stopped = design((a, b), noise, limits, SearchOptions(starts=1, refine=0, draws=0, rehearse=0,
                                                          families=("chirp",), push=0))
    assert stopped.best.score == pytest.approx(stopped.reference.score) and stopped.beats_reference is False
    assert "motor speed limit" in stopped.unbeaten and len(d.evaluated) > len(stopped.evaluated)


def test_an_inputs_noise_floor_is_its_own_recordings_windowed_prediction_error(pair_evaluator):
    """The floor grows with the motion: the rivals' own windowed prediction of a fast one-way
    rotation errs more in q (start velocity from quantised angles) than of a small slow sine."""
    from mjjoint.design.criterion import input_floor
    a, b, limits, noise = pair_evaluator
    ev = Evaluator((a, b), None, limits, SearchOptions(draws=0))
    t = np.arange(limits.samples) / limits.rate
    slow = ev.input("sine", (), None, 0.02 * np.sin(2 * np.pi * 0.5 * t))
    fast = ev.input("one way", (), None, np.full(limits.samples, 0.09), score_past_limits=True)  # past the speed limit
    assert slow.floor == input_floor(ev.models, slow.traces, ev.window)  # deterministic
    assert fast.floor["q"] > 10 * slow.floor["q"] > 0
    assert all(v > 0 for v in slow.floor.values())


def test_closed_loop_inputs_are_references_the_saturated_controller_tracks_within_the_limits(pair_evaluator,
                                                                                              tmp_path):
    from mjjoint.design import design
    from mjjoint.design.export import write_experiment
    from mjjoint.rehearse import Controller, ReferenceFile
    a, b, limits, noise = pair_evaluator
    d = design((a, b), noise, limits, SearchOptions(starts=2, refine=0, draws=0, rehearse=0,
                                                    families=("slow_reversal",)), loop=Controller())
    assert d.loop.u_max == limits.max_torque
    for tr in d.best.traces:
        assert np.max(np.abs(tr.u)) <= limits.max_torque * (1 + 1e-12)  # the command saturates
        assert np.max(np.abs(tr.theta - tr.theta[0])) <= limits.angle_range
    assert np.max(np.abs(d.best.u)) <= limits.angle_range and d.best.score > 0
    ref = ReferenceFile(write_experiment(d, tmp_path / "experiment.csv"))
    assert ref.side == "link" and np.array_equal(ref.sample(limits.rate, limits.duration), d.best.u)
