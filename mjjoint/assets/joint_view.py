"""One joint of a serial arm seen as the single arm: its own bodies, the rest frozen as a load.

``fit`` and ``diagnose`` work on the single-joint model (``identify.structure``): a rotor, a
gear, a hub and a rod with a weight at its end, hanging at theta = 0. For joint j of a
``[[joint]]`` model file that model keeps joint j's own physics and bodies (rotor, hub, rod)
and replaces everything its rod end carries (the next joints' housings, rotors, hubs, rods
and weights) by the same rigid load at the home pose, as in the locked-elbow test of
tests/test_multijoint.py. Both sides are measured on the compiled models at home:

- the weight at the rod end makes the link's static moment about the axis the chain's, so
  gravity pulls on the link as it does at home;
- the hub makes up the rest of the inertia about the axis (the single arm draws its weight
  as a sphere of fixed radius, whose own inertia is counted);
- gravity is the component across the axis, g |a x z| (0 for a vertical axis).

With the other joints locked this is exact (tests/test_multijoint_diagnose.py). What it
cannot hold is the coupling: when the other joints move, their inertia, Coriolis and gravity
forces act on joint j as a load the single-joint model does not have.
"""
from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from ..modelfile import ModelFile
from .builder import ArmSpec, build_arm, load_model
from .serial_file import SerialArmFile

HANGING_TOLERANCE = math.radians(1.0)  # a link's static moment this far off "down" is noted


def _subtree(model: mujoco.MjModel, root: int) -> list[int]:
    """Bodies at or below ``root`` (MuJoCo orders parents before children)."""
    inside = {root}
    for b in range(root + 1, model.nbody):
        if model.body_parentid[b] in inside:
            inside.add(b)
    return sorted(inside)


def _load_about_axis(model: mujoco.MjModel, data: mujoco.MjData, bodies: list[int], anchor: np.ndarray,
                     axis: np.ndarray) -> tuple[np.ndarray, float]:
    """(static moment vector across the axis [kg m], inertia about the axis [kg m^2]) of ``bodies``."""
    moment, inertia = np.zeros(3), 0.0
    for b in bodies:
        m = model.body_mass[b]
        r = data.xipos[b] - anchor
        r_perp = r - (r @ axis) * axis
        rot = data.ximat[b].reshape(3, 3)
        moment += m * r_perp
        inertia += m * (r_perp @ r_perp) + axis @ rot @ np.diag(model.body_inertia[b]) @ rot.T @ axis
    return moment, float(inertia)


def _link_load(model: mujoco.MjModel, data: mujoco.MjData, hub: str, link: str) -> tuple[np.ndarray, float, np.ndarray]:
    """(static moment vector, inertia about the axis, axis) of everything the hinge ``link`` turns."""
    jid = model.joint(link).id
    axis = data.xaxis[jid].copy()
    moment, inertia = _load_about_axis(model, data, _subtree(model, model.body(hub).id), data.xanchor[jid], axis)
    return moment, inertia, axis


def _at_home(model: mujoco.MjModel) -> mujoco.MjData:
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    return data


def _single_link(arm: ArmSpec, joint) -> tuple[float, float]:
    """(static moment, inertia about the axis) of the single arm's link, as MuJoCo compiles it."""
    model = load_model(build_arm(arm, joint, scene=False))
    moment, inertia, _ = _link_load(model, _at_home(model), "hub", "link")
    return float(np.linalg.norm(moment)), inertia


def single_joint_models(arm: SerialArmFile) -> list[tuple[ModelFile, list[str]]]:
    """Per joint (in order): the single-joint model file that stands for it, and notes."""
    model = arm.compile()
    data = _at_home(model)
    down = np.array([0.0, 0.0, -1.0])
    out = []
    for j, js in enumerate(arm.joints, start=1):
        moment, inertia, axis = _link_load(model, data, f"hub{j}", f"link{j}")
        across = float(np.linalg.norm(np.cross(axis, down)))  # |a x z|: gravity's share across the axis
        single = dataclasses.replace(js.arm_spec(), input_delay=0.0, gravity=arm.world.gravity * across,
                                     timestep=arm.world.timestep)
        # Both are linear: the tip weight sets the static moment, the hub the remaining inertia
        # (the single arm draws its weight as a sphere, whose own inertia the hub makes up).
        s_single, _ = _single_link(single, js.joint)
        single = dataclasses.replace(single, tip_mass=single.tip_mass + (np.linalg.norm(moment) - s_single) / js.rod_length)
        _, i_single = _single_link(single, js.joint)
        notes = []
        if single.hub_inertia + inertia - i_single > 0:
            single = dataclasses.replace(single, hub_inertia=single.hub_inertia + inertia - i_single)
        else:  # a heavy load close to a point: the drawn sphere alone turns harder than the chain
            notes.append(f"link {j}: the single arm's weight has {i_single - inertia:.3g} kg m^2 more inertia "
                         "than the load it stands for; kept")
        if across > 1e-9:
            # The single arm hangs at theta = 0: its gravity torque is -m g l sin(theta).
            hang = down - (down @ axis) * axis
            angle = math.atan2(np.linalg.norm(np.cross(moment, hang)), moment @ hang)
            if angle > HANGING_TOLERANCE:
                notes.append(f"link {j} does not hang at theta = 0 (its weight sits {math.degrees(angle):.0f} deg "
                             "off); the single-joint gravity term, zero there, cannot match it")
        out.append((ModelFile(arm=single, joint=js.joint, sample_rate=arm.sample_rate), notes))
    return out
