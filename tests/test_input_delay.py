"""The input delay (ArmSpec.input_delay, MuJoCo's native actuator delay) delivers the delay declared.

A held input delayed by d loses d x its step in impulse, whatever d is against the step h. With
MuJoCo's default zero-order hold of the control history, d was rounded up to the next step
(1.6 ms delivered 2.0 ms at h = 0.5 ms: the concealed input_delay case of seed 4 then "fitted"
1.96 ms against a declared 1.60). The identification's windows read the recorded input as that
delay does, so the model they predict is the MJCF a simulation runs.
"""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjjoint.assets import ArmSpec, build_arm
from mjjoint.joint import JointParams
from mjjoint.excitation import Multisine
from mjjoint.identify.windows import Measured, Predictor
from mjjoint.recordings import Recording
from mjjoint.sim import held_controls, joint_indices, simulate


@pytest.mark.parametrize("delay, timestep", [(1.6e-3, 5e-4), (1.75e-3, 5e-4), (2.0e-3, 5e-4), (2.3e-3, 5e-4),
                                             (7.1e-3, 5e-4), (4.0e-3, 6.25e-5), (1e-2, 2.5e-4)])
def test_a_delayed_torque_step_arrives_late_by_the_declared_delay_in_impulse(delay, timestep):
    # At the finer steps a flexible rod's model runs at, the history still holds the longest
    # delay the identification fits (10 ms).
    model = build_arm(ArmSpec(segments=0, input_delay=delay, timestep=timestep), JointParams(), scene=False).compile()
    data = mujoco.MjData(model)
    ji = joint_indices(model)[0]
    h = model.opt.timestep
    edge, steps = 10, 10 + int(np.ceil(delay / h)) + 10
    force = []
    for k in range(steps):
        data.ctrl[ji.actuator] = 1.0 if k >= edge else 0.0  # set before each step, held over it
        mujoco.mj_step(model, data)
        force.append(data.actuator_force[ji.actuator])
    force = np.array(force)
    full = force[-1]
    assert full > 0 and np.all(force[:edge] == 0.0)
    lost = h * np.sum(1.0 - force[edge:] / full)
    assert lost == pytest.approx(delay, abs=1e-9)


def test_a_delay_longer_than_the_history_is_refused_with_its_range():
    with pytest.raises(ValueError, match=r"input_delay=0.0101 is outside the allowed range \[0, 0.01\]"):
        ArmSpec(input_delay=0.0101, timestep=2.5e-4)


@pytest.mark.parametrize("delay", [0.0, 1.0e-3, 1.25e-3, 1.6e-3, 2.3e-3])
def test_the_windows_read_the_input_as_the_native_delay_delivers_it(delay):
    """A window's controls, from any sample, are the controls MuJoCo's delay hands on from the
    held input (``sim.held_controls``), to the rounding of the input's running integral the
    windows read it from (1e-10 of a 0.1 N m input), with d on a step or between two: a read of
    the held input itself shifted by d smooths it differently between the steps (up to 0.09 of a
    0.1 N m rms input; the true delay fitted 1.5 us short at 2.25 ms)."""
    arm = ArmSpec(segments=0, input_delay=delay)
    u = Multisine(amplitude=0.1, f_min=1.0, f_max=200.0, seed=2).sample(1000.0, 3.0)
    trace = simulate(u, arm=ArmSpec(segments=0), joint=JointParams())
    rec = Recording(t=trace.t, u=u, q=trace.q, theta=trace.theta, tau=trace.tau)
    predictor = Predictor(Measured.from_recording(rec, 160.0))
    model = build_arm(arm, JointParams(), scene=False).compile()
    data = mujoco.MjData(model)
    ji = joint_indices(model)[0]
    delivered = []
    for c in held_controls(u / ji.k_m, predictor._substeps(model)):
        data.ctrl[ji.actuator] = c
        mujoco.mj_step(model, data)
        delivered.append(data.actuator_force[ji.actuator])  # the control the delay hands on
    delivered = np.array(delivered)
    for first in (0, 37, 1500):
        ctrl = predictor._controls(model, np.array([first]), 200, delay, ji)[0, :, ji.actuator]
        sub = predictor._substeps(model)
        np.testing.assert_allclose(ctrl, delivered[first * sub:first * sub + len(ctrl)], rtol=0, atol=1e-10)
