"""The noise floor a verdict is judged against (diagnosis/floor.py) and the window starts of a
flexible link (identify/windows.py), which set how low that floor can be."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mjjoint import Multisine, Simulator
from mjjoint.assets import ArmSpec
from mjjoint.diagnosis.floor import EXPLAINED_RATIO, RESOLUTION, WINDOWING_TRUST, Floor, noise_floor
from mjjoint.identify.twin import analog_noise, quantisation_step, sensor_noise
from mjjoint.identify import windows
from mjjoint.identify.fit import evaluate
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import Recording

RATE = 1000.0
N = 160.0
LSB = 2 * math.pi / 2 ** 15
TAU_NOISE = 0.01  # [N m]


def _recording(truth: Structure, seconds: float, seed: int = 0) -> Recording:
    """The truth under a multisine, with a 15-bit motor resolver and a noisy torque cell."""
    u = Multisine(amplitude=0.3).sample(RATE, seconds)
    tr = Simulator(truth.compile(), sample_rate=RATE).run(u)
    rng = np.random.default_rng(seed)
    q = np.round(tr.q / LSB) * LSB
    tau = tr.tau + rng.normal(0.0, TAU_NOISE, len(tr.tau))
    return Recording(t=tr.t, u=tr.u, q=q, theta=tr.theta, tau=tau, gear_ratio=N, meta={})


def _predictor(rec: Recording) -> Predictor:
    return Predictor(Measured.from_recording(rec, N), WindowDesign())


@pytest.fixture(scope="module")
def rigid():
    truth = Structure.create(("coulomb_friction", "viscous_friction", "linear_stiffness", "transmission_damping"),
                             ArmSpec(segments=0), N)
    return truth, _predictor(_recording(truth, 6.0))


def test_quantisation_step_is_found_and_a_float_signal_has_none():
    t = np.arange(5000) / RATE
    x = 0.3 * np.sin(2 * np.pi * 1.3 * t) + 0.05 * np.sin(2 * np.pi * 7.0 * t)
    assert quantisation_step(np.round(x / LSB) * LSB) == pytest.approx(LSB, rel=1e-6)
    assert quantisation_step(x) == 0.0


def test_white_noise_is_estimated_on_a_moving_signal():
    t = np.arange(20000) / RATE
    rng = np.random.default_rng(1)
    x = 2.0 * np.sin(2 * np.pi * 0.8 * t) + rng.normal(0.0, 0.01, t.size)
    sigma, step = sensor_noise(x, RATE)
    assert step == 0.0 and sigma == pytest.approx(0.01, rel=0.15)


def test_a_quantised_recording_keeps_its_steps_when_its_time_stamps_are_rounded():
    """Stamps printed to a few digits sit on the uniform grid but for 1e-16: the samples are
    taken as they are, not blended into values the encoder cannot read."""
    t = np.round(np.arange(6000) * 0.001, 3)  # as a CSV gives them back
    q = np.round((0.3 * np.sin(2 * np.pi * 1.3 * t) + 0.05 * np.sin(2 * np.pi * 7.0 * t)) / LSB) * LSB
    m = Measured.from_recording(Recording(t=t, u=0 * t, q=q, theta=q / N, tau=0 * t), N)
    np.testing.assert_array_equal(m.q, q)
    assert quantisation_step(m.q) == pytest.approx(LSB, rel=1e-6)
    # Stamps that are really off the grid are still resampled onto it.
    jittered = t + 0.2e-3 * np.sin(np.arange(t.size))
    m = Measured.from_recording(Recording(t=jittered, u=0 * t, q=q, theta=q / N, tau=0 * t), N)
    assert not np.array_equal(m.q, q)


def test_a_twin_of_a_sensor_that_only_rounds_draws_no_noise_before_rounding():
    """What the noise estimator reads off a rounded signal is the rounding's, so the twin draws
    only the noise beyond it: none for an encoder, the analog noise where there is some."""
    t = np.arange(8000) / RATE
    x = 30.0 * np.sin(2 * np.pi * 0.5 * t) + 2.0 * np.sin(2 * np.pi * 6.0 * t)
    step = 2 * math.pi / 2 ** 12
    m = Measured.from_recording(Recording(t=t, u=0 * t, q=x, theta=x / N, tau=0 * t), N)
    for sigma in (0.0, 2e-3):
        noisy = x + np.random.default_rng(3).normal(0.0, sigma, t.size)
        noise, found = sensor_noise(np.round(noisy / step) * step, RATE)
        assert found == pytest.approx(step, rel=1e-6)
        analog = analog_noise(x, noise, found, m)
        assert analog == pytest.approx(sigma, abs=0.25 * 2e-3), (sigma, analog, noise)


def test_the_right_model_is_explained_and_a_model_missing_physics_is_not(rigid):
    truth, predictor = rigid
    floor = noise_floor(predictor, truth)
    nrmse = evaluate(predictor, truth)[3]
    assert floor.twin and floor.explained(nrmse), (floor.ratios(nrmse), floor.nrmse)
    # The torque cell's noise shows in tau's measurement floor (std / spread within windows).
    assert floor.noise["tau"] == pytest.approx(TAU_NOISE, rel=0.25)
    lacking = truth.with_values({"coulomb_friction.fc": 1e-3 * truth.values["coulomb_friction.fc"]})
    lacking_nrmse = evaluate(predictor, lacking)[3]
    assert not noise_floor(predictor, lacking).explained(lacking_nrmse)
    assert max(noise_floor(predictor, lacking).ratios(lacking_nrmse).values()) > EXPLAINED_RATIO


def test_the_floors_cost_is_over_the_signals_the_fit_scores(rigid):
    """The absolute gain an effect must reach is a share of the floor's cost, in the fit's cost
    units: scored on q alone, the floors of theta, delta and tau do not count (a deflection far
    above its floor made that gain 46x the whole model's cost on a real robot's motor angle)."""
    truth, predictor = rigid
    q_only = Predictor(predictor.m, WindowDesign(), fit_signals=("q",))
    floor = noise_floor(q_only, truth)
    assert set(floor.nrmse) == {"q", "theta", "delta", "tau"}  # each still reported
    assert floor.cost() == pytest.approx(floor.nrmse["q"] ** 2)
    every = noise_floor(predictor, truth)
    assert every.cost() == pytest.approx(np.mean([v ** 2 for v in every.nrmse.values()]))


def test_stacked_recordings_give_a_twin_whose_windows_never_start_across_a_join(rigid):
    # Two runs that end and start in different places: the twin's velocities taken across the
    # join would start the window there at the jump's speed (a floor of several times the spread).
    truth, _ = rigid
    runs = [_recording(truth, 3.0, seed) for seed in (0, 1)]
    runs[1] = dataclasses.replace(runs[1], q=runs[1].q + 40.0, theta=runs[1].theta + 40.0 / N)
    stacked = Measured.stack([Measured.from_recording(r, N) for r in runs])
    predictor = Predictor(stacked, WindowDesign(seed=1))
    assert np.any(np.isin(predictor.starts[predictor.test], stacked.joins))  # a held-out window starts there
    floor = noise_floor(predictor, truth)
    single = noise_floor(_predictor(runs[0]), truth)
    assert floor.twin and max(floor.twin.values()) < 3 * max(single.twin.values()), (floor.twin, single.twin)


def test_a_twin_its_model_cannot_predict_sets_no_floor(rigid, monkeypatch):
    # A floor at the signal's own spread would call any model explained.
    truth, predictor = rigid
    monkeypatch.setattr(Predictor, "nrmse", lambda self, pred, windows: {s: 1.2 for s in self.signals})
    floor = noise_floor(predictor, truth)
    assert floor.twin == {} and "could not predict its own twin" in floor.note


def test_a_flexible_links_windows_start_with_the_rod_the_hub_drove(monkeypatch):
    truth = Structure.create(("coulomb_friction", "linear_stiffness", "transmission_damping", "link_flexibility"),
                             ArmSpec(segments=4), N)
    rec = _recording(truth, 5.0)
    with_lead = evaluate(_predictor(rec), truth)[3]
    monkeypatch.setattr(windows, "FLEX_LEAD", 0.0)
    straight = evaluate(_predictor(rec), truth)[3]
    assert with_lead["tau"] < 0.5 * straight["tau"] and with_lead["delta"] < 0.5 * straight["delta"], (with_lead, straight)


def test_an_effect_behind_a_missing_prerequisite_is_screened_with_it():
    from mjjoint.diagnosis.loop import candidates_for, parts
    minimal = Structure.create((), ArmSpec(), N)
    found = candidates_for(minimal)
    assert "linear_stiffness+backlash" in found and "linear_stiffness+transmission_hysteresis" in found
    assert "backlash" not in found and "linear_stiffness" in found
    stiff = minimal.with_effect("linear_stiffness")
    assert "backlash" in candidates_for(stiff) and "linear_stiffness+backlash" not in candidates_for(stiff)
    assert parts("linear_stiffness+backlash") == ("linear_stiffness", "backlash")


def test_a_rigid_gear_on_a_flexible_rod_is_stable():
    # The rigid gear's spring is set by the hub alone once the rod bends (effects.rigid_gear):
    # with the whole link's inertia it was too stiff, and every link_flexibility screen diverged.
    from mjjoint.assets import load_model
    flexible = Structure.create(("link_flexibility",), ArmSpec(), N)
    arm, joint = flexible.model_params()
    load_model(arm=arm, joint=joint)  # checks the model's stability, raising if it is not


def test_parameters_left_on_a_bound_are_named_with_the_bound():
    from types import SimpleNamespace

    from mjjoint.diagnosis.loop import stand_ins
    s = Structure.create(("coulomb_friction", "gravity"), ArmSpec(), N)
    (fc,) = [p for p in s.params if p.name == "coulomb_friction.fc"]
    (g,) = [p for p in s.params if p.name == "gravity.g"]
    at = s.with_values({"coulomb_friction.fc": fc.hi, "gravity.g": g.lo})
    result = SimpleNamespace(structure=at, on_bound=("coulomb_friction.fc", "gravity.g"))
    assert stand_ins(result) == {"coulomb_friction.fc": "upper", "gravity.g": "lower"}


def test_the_twins_windowing_counts_only_up_to_a_multiple_of_what_the_recording_sets():
    """A twin is made by the model under judgement: where its window starts cost far more than the
    sensors' noise, "explained" is not claimed on its word alone, and the verdict says that part of
    the rest may be the windows'. The absolute gain an effect must reach keeps the whole twin."""
    from types import SimpleNamespace

    from mjjoint.diagnosis.loop import mismatch
    recorded, twin = 0.004, 0.028  # a small servo's tau: its twin 2.8x the sensors' floor (0.01)
    floor = Floor(noise={"tau": 0.0}, quantum={"tau": 0.0}, measurement={"tau": recorded}, twin={"tau": twin},
                  signals=("tau",))
    assert floor.recorded["tau"] == RESOLUTION
    assert floor.nrmse["tau"] == pytest.approx(WINDOWING_TRUST * RESOLUTION) and floor.capped == ("tau",)
    assert floor.cost() == pytest.approx(twin ** 2)
    within_twin = {"tau": 0.031}  # within 1.5x its twin, 3.1x the sensors'
    assert within_twin["tau"] <= EXPLAINED_RATIO * twin and not floor.explained(within_twin)
    assert floor.explained({"tau": 0.029})
    text = mismatch(SimpleNamespace(nrmse_test=within_twin), floor, {})
    assert text.startswith("tau held-out NRMSE 0.031 against a floor of 0.02 (its twin 0.028) (a floor counts the "
                           "model's own twin up to 2x the recording's noise;")
    from mjjoint.report.summary import judged_lines
    lines = judged_lines({"noise_floor": floor.as_dict(), "explained": False}, {"tau": 0.05}, within_twin)
    assert lines[0].endswith("floor 0.0200 (twin 0.0280)") and lines[-1] == "explained to the noise: no"
    # A signal reported but not scored (``--fit-signals``) is judged, and said to be unscored.
    both = Floor(noise={"q": 0.0, "delta": 0.0}, quantum={"q": 0.0, "delta": 0.0},
                 measurement={"q": 0.01, "delta": 0.02}, twin={}, signals=("q", "delta"), scored=("q",))
    text = mismatch(SimpleNamespace(nrmse_test={"q": 0.08, "delta": 13.0}), both, {})
    assert text.startswith("delta held-out NRMSE 13 against a floor of 0.02 (a signal the fit does not score), "
                           "q held-out NRMSE 0.08 against a floor of 0.01;")
    # the link angle is scored through the deflection
    three = Floor(noise={"theta": 0.0, "delta": 0.0}, quantum={"theta": 0.0, "delta": 0.0},
                  measurement={"theta": 0.01, "delta": 0.02}, twin={}, signals=("theta", "delta"), scored=("delta",))
    assert "does not score" not in mismatch(SimpleNamespace(nrmse_test={"theta": 0.3, "delta": 0.5}), three, {})
    # A twin within the trusted multiple is the floor as it is.
    near = dataclasses.replace(floor, twin={"tau": 0.015})
    assert near.nrmse["tau"] == 0.015 and near.capped == () and "twin" not in mismatch(
        SimpleNamespace(nrmse_test={"tau": 0.05}), near, {})
