"""Small MJCF models of the chapter's numerical examples, compiled with the plugin registered.

The examples of Sec. 2 are two- and one-inertia systems, not the arm, so each experiment
writes its own few-line MJCF: bodies on y-hinges whose inertia about the axis is the example's
mass, a motor actuator of gear 1 (ctrl = torque), and, where joint physics is involved, an
``mjjoint.joint`` instance whose ``<config>`` is ``JointParams.to_config()``. Models without
the plugin (the rigid joint of Eq. 2, the load of Eq. 10) are pure MuJoCo multibody physics
and are rolled out here; models with it go through ``Simulator``.
"""
from __future__ import annotations

from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from ..assets import load_model
from ..coupling.plugin import PLUGIN_NAME, register
from ..joint import JointParams
from ..params import substeps
from ..sim import held_controls, sample_velocity


def plugin_block(joint: JointParams) -> str:
    """The ``<extension>`` element carrying one joint instance."""
    cfg = "".join(f'<config key={quoteattr(k)} value={quoteattr(v)}/>' for k, v in joint.to_config().items())
    return f'<extension><plugin plugin="{PLUGIN_NAME}"><instance name="joint">{cfg}</instance></plugin></extension>'


def inertia_body(name: str, joint: str, inertia: float, inner: str = "", damping: float = 0.0,
                 stiffness: float = 0.0) -> str:
    """A body on a y-hinge whose moment of inertia about the axis is ``inertia``."""
    return (f'<body name="{name}"><joint name="{joint}" type="hinge" axis="0 1 0" '
            f'damping="{damping!r}" stiffness="{stiffness!r}"/>'
            f'<inertial pos="0 0 0" mass="1" diaginertia="{inertia!r} {inertia!r} {inertia!r}"/>'
            f'{inner}</body>')


def mjcf(name: str, timestep: float, bodies: str, actuated: str, joint: JointParams | None = None) -> str:
    """A gravity-free model: ``bodies`` in the worldbody, a torque motor on joint ``actuated``.

    Euler integration: MuJoCo then treats native joint damping implicitly, and the plugin's
    forces are explicit in every integrator anyway.
    """
    ext = plugin_block(joint) if joint is not None else ""
    return (f'<mujoco model="{name}"><option timestep="{timestep!r}" integrator="Euler" gravity="0 0 0"/>'
            f'{ext}<worldbody>{bodies}</worldbody>'
            f'<actuator><motor name="u" joint="{actuated}" gear="1"/></actuator></mujoco>')


def compile_mjcf(xml: str) -> mujoco.MjModel:
    """Compile an MJCF string; plugin configs are validated by ``load_model``."""
    register()  # the parser must know the plugin before it reads <extension>
    return load_model(mujoco.MjSpec.from_string(xml))


@dataclass(frozen=True)
class Samples:
    """Generalised positions and velocities of a plugin-free model at the sample instants."""

    t: np.ndarray
    qpos: np.ndarray   # (n, nq); row 0 is the initial state
    qvel: np.ndarray   # (n, nv)


def rollout(model: mujoco.MjModel, u: np.ndarray, sample_rate: float) -> Samples:
    """Roll a plugin-free model out from rest under torques ``u`` held over each sample period.

    Same sampling convention as ``Simulator.run``: row k is the state at k / sample_rate, and
    u[k] acts over [k, k+1) / sample_rate.
    """
    sub = substeps(sample_rate, model.opt.timestep)
    data = mujoco.MjData(model)
    x0 = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, x0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    ctrl = held_controls(u, sub)[:, None]
    state, _ = mj_rollout.rollout(model, data, x0[None], ctrl[None])
    every = np.vstack([x0[None], state[0]])  # row i: after i steps
    nq, nv = model.nq, model.nv
    at = sub * np.arange(len(u))
    before = np.vstack([np.full((1, nv), np.nan), every[at[1:] - 1, 1 + nq:1 + nq + nv]])
    return Samples(t=every[at, 0], qpos=every[at, 1:1 + nq],
                   qvel=sample_velocity(every[at, 1 + nq:1 + nq + nv], before))
