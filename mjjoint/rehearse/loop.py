"""The closed loop: a reference, a position controller on sensed angles, the joint in MuJoCo.

Once per sample: read the sensors (``sensors``), compute the command from the sensed
controlled angle (``controller``), hold it over the sample's physics steps. The controller
runs in Python once per sample (this makes recordings; it is not on any fitting path); the
plant, an input delay included if the model has one, is MuJoCo with the mjjoint plugin. The
logged torque is the plugin's transmitted torque at the sample instant, as a torque cell sees it.
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..assets import ArmSpec, build_arm, load_model
from ..coupling.kernels import joint_catch_up, transmitted
from ..coupling.layout import NSTATE
from ..joint import JointParams
from ..params import substeps
from ..sim import FULL, joint_indices, step_held
from .controller import Controller
from .reference import LabProgram, on_side
from .sensors import Sensors

SIGNALS = ("t", "u", "q", "theta", "tau")


@dataclass
class LoopRun:
    """What a closed-loop run logged, and (``keep_states``) the true full-physics states."""

    columns: dict[str, np.ndarray]   # t, u, q, theta, tau as the sensors logged them (SI)
    reference: np.ndarray            # the controlled angle's reference at each sample [rad]
    states: np.ndarray | None        # (n, nstate) at each sample, before its command acts


def _reset(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """The start the Simulator uses: the "home" keyframe if the model has one, else the defaults."""
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "home") if model.nkey else -1
    if key >= 0:
        mujoco.mj_resetDataKeyframe(model, data, key)
    else:
        mujoco.mj_resetData(model, data)


def run_loop(model: mujoco.MjModel, theta_ref: np.ndarray, controller: Controller = Controller(),
             sensors: Sensors = Sensors(), rate: float = 1000.0, keep_states: bool = False) -> LoopRun:
    """Track the link-side reference ``theta_ref`` (one value per sample at ``rate``) in closed loop."""
    joints = joint_indices(model)
    if len(joints) != 1:
        raise ValueError(f"the closed loop drives one joint; the model has {len(joints)}")
    ji = joints[0]
    ji.require_actuator()
    if model.actuator_ctrllimited[ji.actuator]:  # MuJoCo would clamp silently: the log would lie
        top = float(np.min(np.abs(model.actuator_ctrlrange[ji.actuator]))) * ji.k_m
        if controller.u_max > top:
            raise ValueError(f"limit {controller.u_max:g} N m is outside the motor's range (0, {top:g}] N m")
    sub = substeps(rate, model.opt.timestep, "rate")
    if sub < 1 or abs(sub * model.opt.timestep * rate - 1.0) > 1e-9:
        raise ValueError(f"rate={rate:g} Hz must be the model rate 1/timestep={1 / model.opt.timestep:g} Hz "
                         "divided by an integer")
    data = mujoco.MjData(model)
    _reset(model, data)
    n = len(theta_ref)
    ref = on_side(np.asarray(theta_ref, float), "link", controller.on, ji.gear_ratio)
    law, read = controller.law(rate), sensors.reader()
    cols = {k: np.empty(n) for k in SIGNALS}
    states = np.empty((n, mujoco.mj_stateSize(model, FULL))) if keep_states else None
    adr = int(model.plugin_stateadr[ji.instance])
    steps = ji.steps(model)
    for i in range(n):
        st = data.plugin_state[adr:adr + NSTATE].copy()
        joint_catch_up(ji.block, st, data.qpos[ji.motor_qpos], data.qvel[ji.motor_dof],
                       data.qpos[ji.link_qpos], data.qvel[ji.link_dof], data.time, *steps)
        tau = transmitted(ji.block, st, data.qpos[ji.motor_qpos], data.qvel[ji.motor_dof],
                          data.qpos[ji.link_qpos], data.qvel[ji.link_dof])
        q, th, tau_m = read(data.qpos[ji.motor_qpos], data.qpos[ji.link_qpos], tau)
        u = law(ref[i], q if controller.on == "motor" else th)
        cols["t"][i], cols["u"][i], cols["q"][i], cols["theta"][i], cols["tau"][i] = data.time, u, q, th, tau_m
        if states is not None:
            mujoco.mj_getState(model, data, states[i], FULL)
        step_held(model, data, ji.actuator, u / ji.k_m, cols["u"][i - 1] / ji.k_m if i else 0.0, sub)
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:  # MuJoCo reset the data
            raise ValueError(f"closed-loop simulation diverged near t = {cols['t'][i]:.3f} s "
                             "(lower the gains or the reference)")
    return LoopRun(cols, ref, states)


def record(arm: ArmSpec, joint: JointParams, program: LabProgram = LabProgram(),
           controller: Controller = Controller(), sensors: Sensors = Sensors(), rate: float = 1000.0):
    """The lab programme on the arm (``arm``, ``joint``) in closed loop; columns t,u,q,theta,tau."""
    model = load_model(build_arm(arm, joint, scene=False))
    return run_loop(model, program.sample(rate, program.duration), controller, sensors, rate).columns
