"""The load the rest of a moving arm puts on joint j, by inverse dynamics of the measured motion.

Joint j's equation of motion in the arm, over its dofs J (rotor, hub, rod segments), is

    M_JJ(q) qdd_J + M_JK(q) qdd_K + c_J(q, qd) = f_J

with K every other dof and c the Coriolis, centrifugal and gravity forces. The single-joint
view (``assets.joint_view``) has M_JJ and c_J of the arm frozen at home with K locked. The rest
is a generalised force on J that the view lacks, applied to it as qfrc_applied:

    load = [M qdd + c]_J(view)  -  [M(q) qdd + c(q, qd)]_J(arm)

both rigid-body terms (``mj_rne``) at the measured motion: every joint's motor and link angle
from its columns, velocities and accelerations by Savitzky-Golay derivatives; dofs no encoder
sees (flexible rod segments) at rest. The load depends on joint j's own state only through the
difference of the two models, which is zero at home: evaluated on the measured rather than the
predicted motion of joint j, it errs by that difference times the prediction's error.
"""
from __future__ import annotations

import mujoco
import numpy as np

from ..identify.windows import Measured
from ..recordings import MultiRecording
from ..sim import joint_indices

# Accelerations of the measured angles: a Savitzky-Golay second derivative over the window
# starts' velocity span (``windows.VELOCITY_WINDOW``, 7 ms). The load must keep the
# transmission modes (~40 Hz) that ride on the other links' angles: on the parallel-axes test
# arm (tests/test_manipulator.py) spans of 5, 7, 11 and 15 ms left held-out tau NRMSE of 0.009,
# 0.014, 0.03 and 0.05 at the true values, and quantising the encoders (2^14 counts a turn on
# the motor, 2^19 on the link) changed them by < 0.003.


def measured_motion(rec: MultiRecording) -> tuple[np.ndarray, list[tuple[np.ndarray, ...]]]:
    """(the uniform grid of ``Measured.from_recording``, per joint (q, qd, qdd, theta, thetad, thetadd))."""
    out, grid = [], None
    for k in range(1, rec.n_joints + 1):
        m = Measured.from_recording(rec.joint(k), 1.0)
        grid = m.t
        if m.theta is None:
            raise ValueError(f"joint {k} has no theta column: the arm's load needs every joint's q and theta")
        acc = m.acceleration
        out.append((m.q, m.qd, acc["q"], m.theta, m.thetad, acc["theta"]))
    return grid, out


def _rigid_forces(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray, qacc: np.ndarray) -> np.ndarray:
    """M(q) qacc + c(q, qd) per sample (n, nv): the rigid-body forces, no passive or plugin forces."""
    d = mujoco.MjData(model)
    out = np.empty((len(qpos), model.nv))
    for i in range(len(qpos)):
        d.qpos[:], d.qvel[:], d.qacc[:] = qpos[i], qvel[i], qacc[i]
        mujoco.mj_kinematics(model, d)
        mujoco.mj_comPos(model, d)
        mujoco.mj_comVel(model, d)
        mujoco.mj_rne(model, d, 1, out[i])
    return out


def _states(model: mujoco.MjModel, motion: list[tuple[np.ndarray, ...]], joints: list) -> tuple[np.ndarray, ...]:
    """(qpos, qvel, qacc) of ``model`` along the measured motion: plugin joint k's motor and link
    dofs from ``motion[k]``, every other dof at its reference position and at rest."""
    n = len(motion[0][0])
    qpos = np.tile(model.qpos0, (n, 1))
    qvel, qacc = np.zeros((n, model.nv)), np.zeros((n, model.nv))
    for ji, (q, qd, qdd, th, thd, thdd) in zip(joints, motion):
        for qadr, dof, x in ((ji.motor_qpos, ji.motor_dof, (q, qd, qdd)), (ji.link_qpos, ji.link_dof, (th, thd, thdd))):
            if qadr >= 0:
                qpos[:, qadr], qvel[:, dof], qacc[:, dof] = x
    return qpos, qvel, qacc


def _shared_dofs(arm: mujoco.MjModel, view: mujoco.MjModel, j: int) -> list[tuple[int, int]]:
    """(arm dof, view dof) pairs of joint j: motor, link, and rod segments named as the builders
    name them (``flex{j}_{k}`` in a serial arm, ``flex{k}`` in the single arm)."""
    a, v = joint_indices(arm)[j - 1], joint_indices(view)[0]
    pairs = [(a.motor_dof, v.motor_dof), (a.link_dof, v.link_dof)]
    for k in range(1, view.njnt + 1):
        try:
            pairs.append((arm.joint(f"flex{j}_{k}").dofadr[0], view.joint(f"flex{k}").dofadr[0]))
        except KeyError:
            break
    return [(x, y) for x, y in pairs if x >= 0 and y >= 0]


def coupling_load(arm: mujoco.MjModel, view: mujoco.MjModel, rec: MultiRecording, j: int
                  ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(grid, {view joint name: load [N m] per grid sample}): the generalised force the rest of
    ``arm`` puts on joint j's dofs beyond what the single-joint ``view`` holds, along ``rec``."""
    grid, motion = measured_motion(rec)
    arm_forces = _rigid_forces(arm, *_states(arm, motion, joint_indices(arm)))
    view_forces = _rigid_forces(view, *_states(view, [motion[j - 1]], joint_indices(view)[:1]))
    return grid, {mujoco.mj_id2name(view, mujoco.mjtObj.mjOBJ_JOINT, view.dof_jntid[v]): view_forces[:, v] - arm_forces[:, a]
                  for a, v in _shared_dofs(arm, view, j)}
