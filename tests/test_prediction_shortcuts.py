"""What a windowed prediction saves is the same answer, bit for bit: the transmission torque
from each row's settled states without the rotor evaluated, internal-state histories shared
between models whose terms agree, configs parsed once, the heap trimmed in batches."""
from __future__ import annotations

import numpy as np
import pytest

import mjjoint.identify.windows as windows
from mjjoint.benchmark.cases import GEAR_RATIO, make_case
from mjjoint.coupling import plugin
from mjjoint.coupling.kernels import joint_traces
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.joint import JointParams
from mjjoint.physics.boucwen import BoucWen
from mjjoint.physics.transmission import Transmission
from mjjoint.recordings import Recording
from mjjoint.rehearse import LabProgram, record
from mjjoint.sim import Simulator


def test_the_transmission_torque_of_a_row_is_the_full_evaluations():
    """2SEP (whose slow steps are substepped), Bouc-Wen and a play, through sticks and reversals."""
    sim = Simulator(joint=JointParams(transmission=Transmission(backlash=2e-4, hysteresis=BoucWen())))
    t = np.arange(3000) / 1000.0
    u = 0.6 * np.sin(2 * np.pi * 0.7 * t) * (t < 2.0)  # swings, reversals, then rest
    full = sim.rollout_states(u)
    ji = sim.joints[0]
    st, motion = ji.settled(sim.model, full)
    tau, _, _ = joint_traces(ji.block, st, *motion, *ji.steps(sim.model))
    assert np.ptp(tau) > 1.0
    np.testing.assert_array_equal(ji.transmission(sim.model, full), tau)


@pytest.fixture(scope="module")
def lab():
    truth = make_case("dynamic_friction", 0).truth.with_effect("transmission_hysteresis")
    cols = record(*truth.model_params(), LabProgram(duration=3.0, seed=1))
    pred = Predictor(Measured.from_recording(Recording(gear_ratio=GEAR_RATIO, meta={}, **cols), GEAR_RATIO),
                     WindowDesign(seed=0))
    return truth, pred


def _run_counts(monkeypatch) -> dict[str, int]:
    calls = {"friction": 0, "hysteresis": 0}
    for name in calls:
        real = getattr(windows, f"{name}_history")

        def counted(*args, _real=real, _name=name):
            calls[_name] += 1
            return _real(*args)
        monkeypatch.setattr(windows, f"{name}_history", counted)
    return calls


def test_models_whose_terms_agree_share_one_history(lab, monkeypatch):
    truth, pred = lab
    calls = _run_counts(monkeypatch)
    heavier = truth.with_values({"mass.tip": 1.1 * truth.values["mass.tip"]})
    pred._histories.clear()
    shared = pred.predict([truth, heavier])
    assert calls == {"friction": 1, "hysteresis": 1}  # one recording segment, both models
    slower = truth.with_values({"dynamic_friction.b": 0.5 * truth.values["dynamic_friction.b"]})
    pred.predict([slower])
    assert calls == {"friction": 2, "hysteresis": 1}  # the lag gain is 2SEP's, not Bouc-Wen's
    wider = truth.with_values({"transmission_hysteresis.x_u": 2.0 * truth.values["transmission_hysteresis.x_u"]})
    pred.predict([wider])
    assert calls == {"friction": 2, "hysteresis": 2}
    # Each model alone, from an empty memo: the same predictions, bit for bit.
    for structure, got in zip([truth, heavier], shared):
        pred._histories.clear()
        alone = pred.predict([structure])[0]
        for k in got:
            np.testing.assert_array_equal(got[k], alone[k])


def test_the_histories_kept_are_bounded(lab, monkeypatch):
    truth, pred = lab
    monkeypatch.setattr(windows, "HISTORY_BYTES", 1)
    pred._histories.clear()
    for b in (0.5, 0.6, 0.7):
        pred.predict([truth.with_values({"dynamic_friction.b": b * truth.values["dynamic_friction.b"]})])
    assert len(pred._histories) == 1  # the last one only


def test_a_config_is_parsed_once_and_its_errors_said_every_time():
    cfg = JointParams().to_config()
    before = plugin._parsed.cache_info().hits
    assert plugin._parsed(tuple(cfg.items())) is plugin._parsed(tuple(cfg.items()))
    assert plugin._parsed.cache_info().hits > before
    bad = tuple({**cfg, "friction.fc": "-1"}.items())
    for _ in range(2):
        with pytest.raises(ValueError, match="fc"):
            plugin._parsed(bad)


def test_the_heap_is_trimmed_once_enough_has_been_freed(monkeypatch):
    trims = []
    monkeypatch.setattr(windows, "_MALLOC_TRIM", lambda pad: trims.append(pad))
    monkeypatch.setattr(windows, "_UNTRIMMED", [0])
    step = windows.TRIM_BYTES // 4
    for _ in range(4):
        windows.release_freed(step - 1)
    assert trims == []
    windows.release_freed(4)
    assert len(trims) == 1 and windows._UNTRIMMED == [0]
    windows.release_freed()  # asked for at once
    assert len(trims) == 2
