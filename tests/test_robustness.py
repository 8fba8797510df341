"""Any valid parameter set simulates, or is rejected up front naming the stiff parameter.

Hypothesis draws whole joints (friction kind, stiffness polynomial, hysteresis, backlash,
bearing friction) and arms (inertias, segments) across the validated ranges; each either
fails ``load_model`` with a one-line message that names the term and the timestep it would
need, or runs 1 s of band-limited random motor torque without diverging.
"""
from __future__ import annotations

import mujoco
import numpy as np
import pytest
from hypothesis import HealthCheck, event, example, given, settings
from hypothesis import strategies as st

from mjjoint import (ArmSpec, BoucWen, JointParams, LoadFriction, Simulator, StaticFriction,
                     Transmission, TwoSEP)


def logs(lo, hi):
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda e: float(10 ** e))


@st.composite
def joints(draw) -> JointParams:
    fc = draw(logs(1e-3, 0.2))
    fs = fc * draw(st.floats(1.0, 3.0))
    friction = draw(st.sampled_from([
        None,
        StaticFriction(fc=fc, fs=fs, vs=draw(logs(0.05, 5.0)), sigma=draw(logs(1e-6, 1e-3))),
        TwoSEP(fc=fc, fs=fs, vs=draw(logs(0.05, 5.0)), sigma=draw(logs(1e-6, 1e-3)),
               k=draw(logs(10.0, 3e3)), b=draw(logs(0.1, 500.0))),
    ]))
    hyst = draw(st.sampled_from([None, BoucWen(mu=draw(st.floats(0.05, 1.0)),
                                               beta=draw(logs(50.0, 5e3)), gamma=0.0)]))
    tr = Transmission(k1=draw(logs(1e3, 1e5)), k3=draw(st.sampled_from([0.0, draw(logs(1e6, 1e10))])),
                      damping=draw(logs(1e-3, 20.0)), backlash=draw(st.sampled_from([0.0, draw(logs(1e-5, 1e-3))])),
                      hysteresis=hyst)
    load = draw(st.sampled_from([None, LoadFriction(fc=draw(logs(1e-3, 2.0)), viscous=draw(logs(1e-4, 1.0)))]))
    return JointParams(friction=friction, transmission=tr, load_friction=load)


arms = st.builds(ArmSpec, segments=st.sampled_from([0, 2, 4]), tip_mass=st.floats(0.1, 3.0),
                 motor_inertia=logs(2e-5, 1e-3))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(joint=joints(), arm=arms, seed=st.integers(0, 2 ** 16))
@example(joint=JointParams(friction=None, load_friction=None, transmission=Transmission(
    k1=1e3, damping=1.0, hysteresis=BoucWen(mu=0.0625, beta=1e3, gamma=0.0))),
    arm=ArmSpec(segments=0, tip_mass=1.0, motor_inertia=10 ** -4.5), seed=0)  # soft gear, sags 0.12 rad
def test_valid_parameters_simulate_or_are_rejected_up_front(joint, arm, seed):
    try:
        sim = Simulator(arm=arm, joint=joint)
    except ValueError as exc:
        message = str(exc)
        assert "\n" not in message and "timestep <=" in message and "too stiff" in message, message
        event("rejected up front")
        return
    event("simulated")
    rng = np.random.default_rng(seed)
    # Band-limited torque, +-0.3 of the motor's rated 1.3 N m: within the designed range.
    u = np.repeat(rng.uniform(-0.3, 0.3, 50), 20)
    trace = sim.run(u)  # raises ValueError on divergence: that would be a failure here
    assert np.isfinite(trace.q).all() and np.isfinite(trace.tau).all()
    bound = deflection_bound(sim, joint.transmission, u)
    assert np.abs(trace.delta).max() < bound, f"deflection beyond what the loads can cause ({bound:.3g} rad)"


def deflection_bound(sim: Simulator, t: Transmission, u: np.ndarray) -> float:
    """The largest deflection the gear can be driven to without a numerical blow-up: the play,
    plus twice what the loads' total variation deflects its weakest stiffness (mu k1 once the
    Bouc-Wen share has saturated). An undamped spring under a piecewise-constant load stays
    within its current load's deflection plus the oscillation every jump of the load adds, at
    most that jump's; the loads are the motor's torque through the gear (its first value and
    every change) and the link's gravity torque, which can swing between its two extremes
    (m g l held horizontal). A fixed 3x the largest load's failed on a nearly undamped gear
    (damping 0.01) with play, which 50 random steps pumped to 1.1x it in a correct run."""
    m, ji = sim.model, sim.joints[0]
    d = mujoco.MjData(m)
    d.qpos[ji.link_qpos] = np.pi / 2  # horizontal link, at rest: qfrc_bias is gravity alone
    mujoco.mj_forward(m, d)
    variation = abs(u[0]) + np.abs(np.diff(u)).sum()
    load = variation * t.gear_ratio + 2.0 * abs(d.qfrc_bias[ji.link_dof])
    weakest = t.k1 * (t.hysteresis.mu if t.hysteresis is not None else 1.0)
    return t.backlash + 2.0 * load / weakest


def test_rejection_names_the_parameter_and_the_timestep():
    with pytest.raises(ValueError, match=r"transmission.k1/k3 .* needs timestep <= "):
        Simulator(joint=JointParams(transmission=Transmission(k1=1e7)))
