"""Sensor effects: a link encoder or a torque sensor read late (time skew) and a torque sensor's
offset and gain change what is measured, not the physics; injected into a recording, the fit
recovers them."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import mjjoint
from mjjoint.assets import ArmSpec
from mjjoint.benchmark.cases import GEAR_RATIO, make_case
from mjjoint.benchmark.score import write_case_recording
from mjjoint.diagnosis.loop import candidates_for
from mjjoint.identify.effects import EFFECTS, shift_late
from mjjoint.identify.fit import evaluate, fit
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import Recording, read_recording

PHYSICS = ("coulomb_friction", "viscous_friction", "linear_stiffness", "transmission_damping")
TRUTH = {"coulomb_friction.fc": 0.05, "viscous_friction.sigma": 2e-4, "linear_stiffness.k1": 1e4,
         "transmission_damping.d": 1.0}
SENSOR_EFFECTS = tuple(e.name for e in EFFECTS.values() if e.site == "sensor")
INJECTED = {"sensor_skew.lag": 2e-3, "torque_gain.gain": 1.2, "torque_offset.offset": 3.0}


def test_a_late_read_is_the_signal_shifted_by_the_lag():
    x = np.arange(10.0)[None, :] ** 2
    assert np.allclose(shift_late(x, 2.0)[0, 2:], x[0, :-2])
    assert np.allclose(shift_late(x, 0.5)[0, 1:], (x[0, :-1] + x[0, 1:]) / 2)


def test_a_read_beyond_the_ends_follows_the_motion():
    # Read early (a negative lag), a window's last samples need what follows it: a line goes on
    # along its slope, where an end held would miss by the whole motion over the shift.
    line = 3.0 + 0.5 * np.arange(12.0)[None, :]
    for lag in (-2.5, -1.0, 1.0, 2.5):
        assert np.allclose(shift_late(line, lag), line - 0.5 * lag)


def test_the_true_model_of_an_encoder_read_early_explains_its_recording(tmp_path):
    # The link encoder read 2 ms early (the motor's 2 ms late): the truth, which has the skew,
    # predicts the deflection to the noise, as it does read late.
    case = make_case("sensor_skew", 6)
    for lag in (-2e-3, 2e-3):
        truth = Structure.create(case.truth.effects, case.truth.nominal, GEAR_RATIO,
                                 {**case.truth.values, "sensor_skew.lag": lag}, case.truth.settings)
        rec = read_recording(write_case_recording(dataclasses.replace(case, truth=truth), tmp_path / str(lag), 4.0),
                             gear_ratio=GEAR_RATIO)
        nrmse = evaluate(Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(seed=6)), truth)[3]
        assert nrmse["delta"] < 0.01, (lag, nrmse)


def test_skew_and_torque_sensor_errors_are_recovered_where_injected():
    truth = Structure.create(PHYSICS, ArmSpec(segments=0, gravity=0.0), 160.0, TRUTH)
    arm, joint = truth.model_params()
    trace = mjjoint.simulate(mjjoint.Multisine().sample(1000, 6), arm=arm, joint=joint)
    lag = INJECTED["sensor_skew.lag"]
    theta = np.interp(trace.t - lag, trace.t, trace.theta)  # the link encoder reads lag late
    tau = INJECTED["torque_gain.gain"] * trace.tau + INJECTED["torque_offset.offset"]
    rec = Recording(t=trace.t, u=trace.u, q=trace.q, theta=theta, tau=tau)
    pred = Predictor(Measured.from_recording(rec, 160.0), WindowDesign())
    start = truth.with_effect("sensor_skew").with_effect("torque_offset").with_effect("torque_gain")
    res = fit(pred, start, names=tuple(INJECTED), max_iter=15)
    v = res.structure.values
    assert v["sensor_skew.lag"] == pytest.approx(lag, rel=0.1)
    assert v["torque_gain.gain"] == pytest.approx(INJECTED["torque_gain.gain"], rel=0.02)
    assert v["torque_offset.offset"] == pytest.approx(INJECTED["torque_offset.offset"], rel=0.05)


def test_a_torque_sensor_read_late_is_recovered():
    truth = Structure.create(PHYSICS, ArmSpec(segments=0, gravity=0.0), 160.0, TRUTH)
    arm, joint = truth.model_params()
    trace = mjjoint.simulate(mjjoint.Multisine().sample(1000, 6), arm=arm, joint=joint)
    lag = 1.3e-3
    rec = Recording(t=trace.t, u=trace.u, q=trace.q, theta=trace.theta, tau=np.interp(trace.t - lag, trace.t, trace.tau))
    pred = Predictor(Measured.from_recording(rec, 160.0), WindowDesign())
    res = fit(pred, truth.with_effect("torque_skew"), names=("torque_skew.lag",), max_iter=15)
    assert res.structure.values["torque_skew.lag"] == pytest.approx(lag, rel=0.05)


def test_the_diagnosis_screens_the_link_skew_by_default_and_the_torque_sensor_only_when_asked():
    s = Structure.create(PHYSICS, ArmSpec(), 160.0)
    torque_sensor = {"torque_skew", "torque_gain", "torque_offset"}
    assert set(SENSOR_EFFECTS) == torque_sensor | {"sensor_skew"}
    assert "sensor_skew" in candidates_for(s) and not torque_sensor & set(candidates_for(s))
    assert set(candidates_for(s, SENSOR_EFFECTS)) == set(SENSOR_EFFECTS)
    # by default only where the fit scores a signal the skew changes: on a fit of the motor angle
    # alone it would act through the windows' start states alone
    assert "sensor_skew" not in candidates_for(s, scored=("q",))
    assert "sensor_skew" in candidates_for(s, scored=("q", "delta"))
    # asked for, the sensor effects are screened whatever the fit scores
    assert set(candidates_for(s, SENSOR_EFFECTS, scored=("q",))) == set(SENSOR_EFFECTS)
    # a recording whose gear law gives energy back (``gear_law.law_energy``) opens the screen to
    # the torque cell's lag, and to no other effect of the torque sensor
    signed = set(candidates_for(s, shown=("energy_returned",)))
    assert signed - set(candidates_for(s)) == {"torque_skew"}
    assert "torque_skew" not in candidates_for(s, ("sensor_skew",), shown=("energy_returned",))


def test_a_sensor_effect_must_name_the_signals_it_senses():
    from mjjoint.identify.effect import Effect
    with pytest.raises(ValueError, match="senses"):
        Effect("clock_skew", "a sensor read late", (), lambda m, v: m, site="sensor", measure=lambda p, v, r: p,
               plot="time_shift")
    with pytest.raises(ValueError, match="senses"):
        Effect("cable", "a cable to the ground", (), lambda m, v: m, site="link", senses=("theta",), plot="sin_theta")
