"""dm_control ``Physics`` of an mjjoint arm: the whole MuJoCo state, and what the joints read.

dm_control's default ``get_state`` is qpos, qvel, act and plugin_state. That is not enough to
continue an episode exactly: the plugin's internal states carry the time they hold at (they
advance only when ``d->time`` has moved, docs/design.md), and a delayed actuator keeps its input
history. So the state here is MuJoCo's ``mjSTATE_FULLPHYSICS`` (time, qpos, qvel, act, actuator
history, plugin states), and ``set_state`` leaves the data ready to step (``forward``), inside
``reset_context`` or not.
"""
from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco import wrapper

from ..assets import load_model
from ..coupling.kernels import joint_catch_up, transmitted
from ..coupling.plugin import register_model
from ..modelfile import load_model_file
from ..sim import FULL, JointIndex, joint_indices


def compile_model(model: str | Path | mujoco.MjSpec | mujoco.MjModel) -> mujoco.MjModel:
    """A shipped MJCF by its name (``"arm3.xml"``), an MJCF or model-file path, an ``MjSpec``
    (``mjjoint.build_arm(...)``) or a compiled model; validated as ``mjjoint.load_model`` does."""
    if isinstance(model, mujoco.MjModel):
        return model
    if isinstance(model, mujoco.MjSpec):
        return load_model(model)
    return load_model_file(model).compile()


def rod_hinges(model: mujoco.MjModel, joints: list[JointIndex]) -> list[np.ndarray]:
    """For each joint, the ids of the hinges its link carries (the flexible rod's segments):
    every hinge that is no joint's motor or link, by the nearest link body above it."""
    link_body = {int(model.jnt_bodyid[j]): i for i, ji in enumerate(joints) for j in range(model.njnt)
                 if model.jnt_qposadr[j] == ji.link_qpos}
    own = {ji.motor_qpos for ji in joints} | {ji.link_qpos for ji in joints}
    rods: list[list[int]] = [[] for _ in joints]
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE or int(model.jnt_qposadr[j]) in own:
            continue
        body = int(model.jnt_bodyid[j])
        while body and body not in link_body:
            body = int(model.body_parentid[body])
        if body:
            rods[link_body[body]].append(j)
    return [np.array(r, dtype=int) for r in rods]


class JointPhysics(dm_mujoco.Physics):
    """An arm of ``mjjoint.joint`` instances (one or several), as dm_control sees it.

    Per joint i (instance order): the motor angle q_i and link angle theta_i [rad], the
    transmission torque T_i (Eq. 18, the torque cell's quantity) [N m], and the rod's bend
    (the sum of its segment hinges' angles: the tip's slope off the hub's line) [rad].
    """

    @classmethod
    def load(cls, model: str | Path | mujoco.MjSpec | mujoco.MjModel) -> "JointPhysics":
        return cls.from_model(wrapper.MjModel(compile_model(model)))

    def _reload_from_data(self, data) -> None:
        super()._reload_from_data(data)
        # A copied model sits at a new address: register it before reading its parameter rows.
        register_model(self.model.ptr)
        self.joints = joint_indices(self.model.ptr)
        if any(ji.motor_qpos < 0 or ji.link_qpos < 0 for ji in self.joints):
            raise ValueError("every mjjoint.joint instance needs a motor and a link joint here "
                             "(a direct drive or a side fixed to the world has no arm to control)")
        rods = rod_hinges(self.model.ptr, self.joints)
        self.rod_qpos = [self.model.jnt_qposadr[r] for r in rods]
        self._rod_dof = [self.model.jnt_dofadr[r] for r in rods]
        self._motor_qpos = np.array([ji.motor_qpos for ji in self.joints])
        self._link_qpos = np.array([ji.link_qpos for ji in self.joints])

    def get_state(self, sig=None) -> np.ndarray:
        return super().get_state(FULL if sig is None else sig)

    def set_state(self, physics_state, sig=None) -> None:
        state = np.asarray(physics_state, dtype=np.float64)
        size = mujoco.mj_stateSize(self.model.ptr, FULL if sig is None else sig)
        if state.shape != (size,):
            raise ValueError(f"physics state has shape {state.shape}; expected ({size},)")
        super().set_state(state, FULL if sig is None else sig)
        # dm_control's legacy step starts with mj_step2, which uses the positions, velocities
        # and passive forces of the last mj_step1: recompute them for the restored state.
        self.forward()

    def motor_angles(self) -> np.ndarray:
        return self.data.qpos[self._motor_qpos].copy()

    def link_angles(self) -> np.ndarray:
        return self.data.qpos[self._link_qpos].copy()

    def rod_bends(self) -> np.ndarray:
        return np.array([self.data.qpos[r].sum() for r in self.rod_qpos])

    def rod_bend_rates(self) -> np.ndarray:
        return np.array([self.data.qvel[r].sum() for r in self._rod_dof])

    def transmission_torques(self) -> np.ndarray:
        """T_i at the current state: the plugin's states brought to this time on a copy (after
        a plain ``mj_step`` their last update is still pending, docs/design.md)."""
        d = self.data
        out = np.empty(len(self.joints))
        for i, ji in enumerate(self.joints):
            adr = int(self.model.plugin_stateadr[ji.instance])
            st = d.plugin_state[adr:adr + int(self.model.plugin_statenum[ji.instance])].copy()
            args = (d.qpos[ji.motor_qpos], d.qvel[ji.motor_dof], d.qpos[ji.link_qpos], d.qvel[ji.link_dof])
            joint_catch_up(ji.block, st, *args, d.time, *ji.steps(self.model.ptr))
            out[i] = transmitted(ji.block, st, *args)
        return out
