"""Recordings at any uniform rate: the model steps a whole number of times a sample, at the
shipped step where the rate allows it, else at the largest step below it that divides the sample
period (``params.fitting_timestep``), instead of refusing the recording."""
from __future__ import annotations

import pytest

import mjjoint
from mjjoint.assets import ArmSpec
from mjjoint.excitation import Chirp
from mjjoint.joint import JointParams
from mjjoint.params import fitting_timestep, substeps
from mjjoint.physics.friction import StaticFriction
from mjjoint.physics.transmission import Transmission
from mjjoint.recordings import Recording
from mjjoint.sim import simulate

SHIPPED = 5e-4


@pytest.mark.parametrize("rate", [1000.0, 250.0, 2000.0, 4000.0, 3000.0, 800.0, 1024.0, 8000.0])
def test_the_step_divides_the_sample_period_and_is_the_shipped_one_where_it_can_be(rate):
    h = fitting_timestep(rate, SHIPPED)
    assert substeps(rate, h) >= 1  # raises where it does not divide
    if (1.0 / rate) / SHIPPED == round((1.0 / rate) / SHIPPED):
        assert h == SHIPPED  # unchanged to the last bit: results at the usual rates stay as they were
    else:
        assert h < SHIPPED
        # the largest such step: the sample period itself, or one substep fewer is too long
        sub = substeps(rate, h)
        assert h == pytest.approx(1.0 / rate, rel=1e-12) if sub == 1 else (1.0 / rate) / (sub - 1) > SHIPPED


@pytest.mark.parametrize("rate", [4000.0, 800.0])
def test_a_recording_at_a_rate_the_model_rate_is_no_multiple_of_is_fitted(rate):
    """The shipped arm with a linear gear under a chirp through its resonance, recorded at
    ``rate``: the fit recovers the gear stiffness (it was refused: "the recording's rate must be
    the model rate 1/timestep=2000 Hz divided by an integer")."""
    k1 = 3e4
    arm = ArmSpec(segments=0, gravity=0.0, timestep=fitting_timestep(rate, SHIPPED))
    joint = JointParams(friction=StaticFriction(fc=0.05, fs=0.05, sigma=2e-4), load_friction=None,
                        transmission=Transmission(gear_ratio=160.0, k1=k1, k3=0.0, damping=1.0, hysteresis=None))
    trace = simulate(Chirp(f_start=80.0).sample(rate, 4), arm=arm, joint=joint, sample_rate=rate)
    rec = Recording(t=trace.t, u=trace.u, q=trace.q, theta=trace.theta, tau=trace.tau)
    result = mjjoint.fit(rec, gear_ratio=160.0, base=("coulomb_friction", "viscous_friction", "linear_stiffness",
                                                       "transmission_damping"))
    assert result.structure.values["linear_stiffness.k1"] == pytest.approx(k1, rel=0.02)
    assert max(result.nrmse_test.values()) < 0.05, result.nrmse_test


def test_a_slow_recording_is_fitted_below_its_nyquist_frequency():
    """At 100 Hz the initial estimate's 50 Hz low-pass sat on the Nyquist frequency and the fit
    stopped with scipy's "critical frequencies must be 0 < Wn < 1"; the chirp stays below it."""
    rate = 100.0
    arm = ArmSpec(segments=0, gravity=0.0, timestep=fitting_timestep(rate, SHIPPED))
    joint = JointParams(friction=StaticFriction(fc=0.05, fs=0.05, sigma=2e-4), load_friction=None,
                        transmission=Transmission(gear_ratio=160.0, k1=3e4, k3=0.0, damping=1.0, hysteresis=None))
    trace = simulate(Chirp(f_start=10.0).sample(rate, 8), arm=arm, joint=joint, sample_rate=rate)
    rec = Recording(t=trace.t, u=trace.u, q=trace.q, theta=trace.theta, tau=trace.tau)
    values = mjjoint.fit(rec, gear_ratio=160.0, base=("coulomb_friction", "viscous_friction", "linear_stiffness",
                                                       "transmission_damping")).structure.values
    assert values["inertia.motor"] == pytest.approx(arm.motor_inertia, rel=0.05)
    assert values["coulomb_friction.fc"] == pytest.approx(0.05, rel=0.1)
    assert values["linear_stiffness.k1"] == pytest.approx(3e4, rel=0.1)
