"""Two encoders counting from different zeros: the deflection q/N - theta then carries a
constant no gear torque explains. Taken as a deflection, it is a torque of k times it at every
window start (a 0.5 rad offset on the lab gear: 5000 N m against a recorded 20 N m, and a fit
that predicted nothing). The estimate finds it from the torque the gear carries, measured or
left by the motor's equation, and the problem aligns theta with a note."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mjjoint.api.problem import joint_problems
from mjjoint.assets import ArmSpec
from mjjoint.excitation import Chirp
from mjjoint.experiments.servo import geared_recording
from mjjoint.identify.initial import estimate
from mjjoint.recordings import Recording


def _shifted(measured, offset):
    return dataclasses.replace(measured, theta=measured.theta - offset)


@pytest.mark.parametrize("offset", [0.5, -0.02])
def test_an_offset_between_the_encoders_is_found_from_the_measured_torque(offset):
    measured, arm = geared_recording(3e4)
    assert estimate(measured, arm).theta_offset == 0.0
    found = estimate(_shifted(measured, offset), arm).theta_offset
    assert found == pytest.approx(offset, abs=1e-4)


def test_without_the_torque_sensor_it_is_found_from_the_torque_the_motor_leaves():
    slow = Chirp(amplitude=3.0, f_start=5.0)
    measured, arm = geared_recording(3e6, tau=False, tip_mass=500.0, chirp=slow)
    nominal = ArmSpec(segments=0, gravity=0.0)
    assert estimate(measured, nominal).theta_offset == 0.0
    # 2 mrad: on this 3e6 N m/rad gear a torque of 6000 N m, ten times what the gear carries.
    found = estimate(_shifted(measured, 2e-3), nominal).theta_offset
    assert found == pytest.approx(2e-3, rel=0.1)


def test_the_problem_aligns_theta_and_says_so():
    measured, arm = geared_recording(3e4)
    rec = Recording(t=measured.t, u=measured.u, q=measured.q, theta=measured.theta + 0.5, tau=measured.tau)
    with pytest.warns(UserWarning, match="another zero than the motor's"):
        problem = next(iter(joint_problems(rec, dict(gear_ratio=160.0)).values()))
    assert np.max(np.abs(problem.predictor.m.theta - measured.theta)) < 1e-4


@pytest.mark.parametrize("tau", [True, False], ids=["tau", "no tau"])
def test_a_link_encoder_read_late_is_estimated_from_the_deflection(tau):
    """A link encoder read ``lag`` late adds lag theta' to the measured deflection beside the
    gear's T/k: the start of ``sensor_skew.lag`` (a KR300 axis reads 2.5-3.1 ms late this way;
    2.6-2.8 ms by the dataset module's own alignment)."""
    measured, arm = geared_recording(3e6, tau=tau, tip_mass=500.0, chirp=Chirp(amplitude=3.0, f_start=5.0))
    nominal = ArmSpec(segments=0, gravity=0.0)
    t = np.arange(measured.t.size) / measured.rate
    assert abs(estimate(measured, nominal).values["sensor_skew.lag"]) < 1e-4
    late = dataclasses.replace(measured, theta=np.interp(t - 3e-3, t, measured.theta))
    assert estimate(late, nominal).values["sensor_skew.lag"] == pytest.approx(3e-3, rel=0.05)
